//! Terrain mode: a streamed world flown through with a fly camera, sculpted with the editor's
//! tools and bombed.
//!
//! The world is edited by an [`Editor`] made by [`Editor::on_world`]: digging and raising are
//! the editor's strokes (every sculpting tool, mirror images, the line tool) and a bomb's crater
//! is one of its edits, all in its budgeted undo history; its meshes reach the renderer through
//! the same change list as a scene's. This room keeps what only terrain mode has: the fly
//! camera, the bombs and the debris. Independent of egui and wgpu, like [`crate::Studio`].

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use glam::{DVec3, Vec3};
use strata_editor::{Editor, Material, ToolKind, ToolPose};
use strata_mesh::Mesh;
use strata_render::Camera;
use strata_terrain::{Recipe, World, WorldSettings};
use strata_volume::CsgOp;
use strata_volume::brush::{Aabb, SdfBrush};

/// A bomb in flight.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Projectile {
    /// Where it is (grid units).
    pub position: DVec3,
    /// Its velocity (grid units a second).
    pub velocity: DVec3,
    /// Seconds it has flown.
    pub age: f64,
}

/// A piece of debris.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Particle {
    /// Where it is.
    pub position: DVec3,
    /// Its velocity.
    pub velocity: DVec3,
    /// Seconds left.
    pub life: f64,
    /// Its material (colour).
    pub material: u8,
}

/// Keys held and mouse motion this frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FlyInput {
    /// W / S: forward (+1) or back (−1).
    pub forward: f64,
    /// D / A: right (+1) or left (−1).
    pub right: f64,
    /// E / Q: up (+1) or down (−1).
    pub up: f64,
    /// Mouse look, radians of yaw (positive: turn left) and pitch (positive: look down).
    pub look: (f64, f64),
    /// Shift: fly faster.
    pub fast: bool,
}

/// Speed of a bomb (grid units a second) and how long it flies before it fizzles.
pub const BOMB_SPEED: f64 = 160.0;
/// Seconds a bomb flies at most.
pub const BOMB_LIFE: f64 = 4.0;
/// Gravity on bombs and debris (grid units a second²).
pub const GRAVITY: f64 = 30.0;

/// Terrain mode's own state: the fly camera, bombs and debris (the world is in its editor).
#[derive(Debug)]
pub struct TerrainMode {
    /// The eye (grid units; a terrain cell is one world unit).
    pub eye: DVec3,
    /// Radians about +y.
    pub yaw: f64,
    /// Radians the view looks down (negative: up).
    pub pitch: f64,
    /// Flying speed (grid units a second).
    pub speed: f64,
    /// Crater radius (grid units).
    pub crater_radius: f64,
    /// Bombs in flight.
    pub projectiles: Vec<Projectile>,
    /// Debris.
    pub particles: Vec<Particle>,
    /// Craters blasted.
    pub craters: usize,
    /// The scene's editor and camera, waiting while the world is open (the studio's).
    pub scene: Option<Box<(Editor, Camera)>>,
    seed: u64,
}

/// The note under which a world remembers where its viewer was.
const VIEWER_NOTE: &str = "viewer";

/// The radius the tools start with in a world (grid units: a world's cell is one unit).
pub const WORLD_BRUSH_RADIUS: f64 = 4.0;

impl TerrainMode {
    /// A new world file at `path` from `recipe`, and the editor on it (coloured by `materials`).
    pub fn create(
        path: &Path,
        recipe: &Recipe,
        settings: WorldSettings,
        materials: Vec<Material>,
    ) -> Result<(Self, Editor), String> {
        let world = World::create(path, recipe, settings).map_err(|e| e.to_string())?;
        Ok(Self::around(world, None, materials))
    }

    /// A world of `recipe` in memory only (previews, screenshots, tests), and its editor.
    pub fn in_memory(
        recipe: &Recipe,
        settings: WorldSettings,
        materials: Vec<Material>,
    ) -> Result<(Self, Editor), String> {
        let world = World::in_memory(recipe, settings).map_err(|e| e.to_string())?;
        Ok(Self::around(world, None, materials))
    }

    /// Opens the world file at `path`, where its viewer last was, and its editor.
    pub fn open(path: &Path, settings: WorldSettings, materials: Vec<Material>) -> Result<(Self, Editor), String> {
        let world = World::open(path, settings).map_err(|e| e.to_string())?;
        let viewer = world.store().and_then(|s| s.note(VIEWER_NOTE).ok().flatten()).and_then(|b| {
            let v: [f64; 5] = postcard::from_bytes(&b).ok()?;
            v.iter().all(|x| x.is_finite()).then_some(v)
        });
        Ok(Self::around(world, viewer, materials))
    }

    /// Terrain mode on a world an editor already holds (one that arrived from a shared room):
    /// above the ground at the origin, with no scene waiting.
    pub fn viewing(world: &World) -> Self {
        Self::mode_at(world, None)
    }

    fn around(world: World, viewer: Option<[f64; 5]>, materials: Vec<Material>) -> (Self, Editor) {
        let mode = Self::mode_at(&world, viewer);
        let mut editor = Editor::on_world(world, materials);
        // The tools start as a dig: erase with a ball (Ctrl raises, Shift smooths).
        editor.tool.kind = ToolKind::Erase;
        editor.tool.radius = WORLD_BRUSH_RADIUS;
        (mode, editor)
    }

    fn mode_at(world: &World, viewer: Option<[f64; 5]>) -> Self {
        let (eye, yaw, pitch) = match viewer {
            Some([x, y, z, yaw, pitch]) => (DVec3::new(x, y, z), yaw, pitch),
            None => {
                // Above the ground at the origin, looking along +x and a little down.
                let r = world.recipe();
                let ground = world.field().height(0.0, 0.0).max(r.heights.base);
                (DVec3::new(0.0, ground + 24.0, 0.0), -std::f64::consts::FRAC_PI_2, 0.25)
            }
        };
        TerrainMode {
            eye,
            yaw,
            pitch,
            speed: 40.0,
            crater_radius: 9.0,
            projectiles: Vec::new(),
            particles: Vec::new(),
            craters: 0,
            scene: None,
            seed: 0x9E37_79B9_7F4A_7C15,
        }
    }

    /// Streams and meshes until everything in view is loaded and meshed, or `timeout` passes;
    /// returns whether it all was.
    pub fn settle(&mut self, editor: &mut Editor, timeout: Duration) -> bool {
        let start = Instant::now();
        let eye = self.eye;
        let streamed = editor.world_mut().is_some_and(|w| w.settle(&[eye], timeout));
        loop {
            self.tick(editor, 0.0);
            let _ = editor.frame(&ToolPose::default(), Duration::from_millis(50));
            if editor.pending() == 0 || start.elapsed() > timeout {
                break;
            }
            std::thread::sleep(Duration::from_millis(1));
        }
        streamed && editor.pending() == 0
    }

    /// The world file of `editor`'s world.
    pub fn path(editor: &Editor) -> Option<PathBuf> {
        editor.world()?.store().map(|s| s.path().to_path_buf())
    }

    /// The direction the eye looks along.
    pub fn forward(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        -DVec3::new(cp * sy, sp, cp * cy)
    }

    /// The renderer's camera for the fly view: an orbit camera one unit in front of the eye.
    pub fn camera(&self) -> Camera {
        let forward = self.forward();
        Camera {
            target: (self.eye + forward).as_vec3(),
            distance: 1.0,
            yaw: self.yaw as f32,
            pitch: self.pitch as f32,
            fov_y: 1.0,
            orthographic: false,
        }
    }

    /// Moves and turns the eye.
    pub fn fly(&mut self, input: FlyInput, dt: f64) {
        if !(dt.is_finite() && dt >= 0.0) {
            return;
        }
        let dt = dt.min(0.25);
        let (dyaw, dpitch) = input.look;
        if dyaw.is_finite() && dpitch.is_finite() {
            self.yaw = (self.yaw + dyaw).rem_euclid(std::f64::consts::TAU);
            self.pitch = (self.pitch + dpitch).clamp(-1.5, 1.5);
        }
        let f = self.forward();
        let flat = DVec3::new(f.x, 0.0, f.z).normalize_or(DVec3::X);
        let right = flat.cross(DVec3::Y);
        let speed = self.speed * if input.fast { 4.0 } else { 1.0 };
        let step = f * input.forward.clamp(-1.0, 1.0)
            + right * input.right.clamp(-1.0, 1.0)
            + DVec3::Y * input.up.clamp(-1.0, 1.0);
        if step.is_finite() {
            self.eye += step * speed * dt;
        }
    }

    /// One frame of what terrain mode adds to the editor's: stream the world around the eye
    /// (its chunks are meshed by the editor's next frame, nearest the eye first), fly the bombs
    /// (blasting a crater where one hits) and the debris.
    pub fn tick(&mut self, editor: &mut Editor, dt: f64) {
        let dt = if dt.is_finite() { dt.clamp(0.0, 0.25) } else { 0.0 };
        editor.stream(self.eye);
        self.fly_bombs(editor, dt);
        for p in &mut self.particles {
            p.velocity.y -= GRAVITY * dt;
            p.position += p.velocity * dt;
            p.life -= dt;
        }
        self.particles.retain(|p| p.life > 0.0);
    }

    fn fly_bombs(&mut self, editor: &mut Editor, dt: f64) {
        let Some(world) = editor.world() else { return };
        let mut hits = Vec::new();
        for b in &mut self.projectiles {
            let step = b.velocity * dt;
            let len = step.length();
            if len > 0.0
                && let Some(hit) = world.volume().raycast(b.position, step / len, len)
            {
                hits.push(hit.point);
                b.age = f64::INFINITY;
                continue;
            }
            b.position += step;
            b.velocity.y -= GRAVITY * dt;
            b.age += dt;
        }
        self.projectiles.retain(|b| b.age < BOMB_LIFE);
        for at in hits {
            // A crater that cannot be blasted (its chunks unreadable) leaves the world as it is.
            let _ = self.blast(editor, at);
        }
    }

    /// Launches a bomb from the eye along the view.
    pub fn bomb(&mut self) {
        let f = self.forward();
        self.projectiles.push(Projectile { position: self.eye + f * 2.0, velocity: f * BOMB_SPEED, age: 0.0 });
    }

    fn random(&mut self) -> f64 {
        self.seed ^= self.seed << 13;
        self.seed ^= self.seed >> 7;
        self.seed ^= self.seed << 17;
        (self.seed >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Blasts a crater at `at`: a rough ball (a sphere whose radius wobbles with direction)
    /// subtracted from the world as one step of the editor's history, and a burst of debris in
    /// the materials it took.
    pub fn blast(&mut self, editor: &mut Editor, at: DVec3) -> Result<(), String> {
        let r = self.crater_radius;
        let (a, b, c) = (self.random() * 6.0, self.random() * 6.0, self.random() * 6.0);
        let rough = move |p: DVec3| {
            let d = p - at;
            let len = d.length();
            let n = if len > 0.0 { d / len } else { DVec3::X };
            let wobble = 0.18 * ((n.x * 5.0 + a).sin() * (n.y * 4.0 + b).sin() + (n.z * 6.0 + c).sin() * 0.5);
            len - r * (1.0 + wobble)
        };
        let bounds = Aabb::new(at - DVec3::splat(r * 1.4), at + DVec3::splat(r * 1.4));
        // The field is a distance to a star-shaped surface: its gradient grows with the wobble's
        // angular frequency over the radius, bounded by 1 + 0.18 · 7.
        let brush = SdfBrush::new(rough, bounds, 2.3).map_err(|e| e.to_string())?;
        let world = editor.world().ok_or("bombs need a world")?;
        let material = world.volume().material_near(at).unwrap_or(1);
        editor.apply(editor.active_surface(), CsgOp::Subtract, &brush).map_err(|e| e.to_string())?;
        self.craters += 1;
        for _ in 0..60 {
            let dir =
                DVec3::new(self.random() - 0.5, self.random() * 0.8 + 0.2, self.random() - 0.5).normalize_or(DVec3::Y);
            let speed = 15.0 + self.random() * 30.0;
            let life = 1.0 + self.random() * 1.5;
            self.particles.push(Particle { position: at + dir * r * 0.5, velocity: dir * speed, life, material });
        }
        Ok(())
    }

    /// The debris (and the bombs in flight) as one mesh of small cubes, in their materials.
    pub fn particle_mesh(&self) -> Mesh {
        let mut mesh = Mesh::default();
        let cubes = self
            .particles
            .iter()
            .map(|p| (p.position, 0.35, p.material))
            .chain(self.projectiles.iter().map(|b| (b.position, 0.6, 5)));
        for (c, s, material) in cubes {
            let c = c.as_vec3();
            let s = s as f32;
            // Six faces, four vertices each, flat normals.
            for axis in 0..3 {
                for sign in [-1.0f32, 1.0] {
                    let mut n = Vec3::ZERO;
                    n[axis] = sign;
                    let (u, v) = (Vec3::AXES[(axis + 1) % 3], Vec3::AXES[(axis + 2) % 3]);
                    let base = mesh.positions.len() as u32;
                    for (du, dv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
                        let p = c + (n + u * du + v * dv) * s;
                        mesh.push_vertex(
                            p.to_array(),
                            n.to_array(),
                            strata_mesh::VertexMaterial::single(material),
                            true,
                        );
                    }
                    let quad = if sign > 0.0 { [0, 1, 2, 0, 2, 3] } else { [0, 2, 1, 0, 3, 2] };
                    mesh.indices.extend(quad.iter().map(|i| base + i));
                }
            }
        }
        mesh
    }

    /// Remembers where the viewer is and writes every edit of `editor`'s world (also done on
    /// drop by the world, without the viewer).
    pub fn save(&self, editor: &mut Editor) -> Result<usize, String> {
        let v = [self.eye.x, self.eye.y, self.eye.z, self.yaw, self.pitch];
        let world = editor.world_mut().ok_or("no world is open")?;
        world.set_note(VIEWER_NOTE, postcard::to_allocvec(&v).expect("five numbers serialise"));
        world.flush().map_err(|e| e.to_string())
    }

    /// A line for the status bar.
    pub fn status(&self, editor: &Editor) -> String {
        let Some(world) = editor.world() else { return String::new() };
        format!(
            "Terrain {}: at ({:.0}, {:.0}, {:.0}); {} chunks loaded (surface {}), {} triangles, {} waiting; {} craters; history {} steps; {} edits not yet written",
            Self::path(editor).map_or("(in memory)".into(), |p| p.display().to_string()),
            self.eye.x,
            self.eye.y,
            self.eye.z,
            world.loaded_count(),
            crate::studio::chunk_levels(world.volume()),
            editor.triangle_count(),
            editor.pending(),
            self.craters,
            editor.history().undo_len(),
            world.unflushed()
        )
    }
}
