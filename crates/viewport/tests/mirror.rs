//! The change lists keep a renderer equal to one that uploads the whole scene anew: after
//! strokes, undo and redo, hidden and moved layers, new materials, another mesher and frames
//! whose remesh budget leaves work for later, the mirrored renderer holds the same meshes and
//! draws the same image as a fresh upload.
//!
//! Without a GPU adapter (not even lavapipe) the test skips with a message, unless
//! `STRATA_REQUIRE_GPU=1` is set (CI sets it).

use std::time::Duration;

use glam::{DQuat, DVec3};
use strata_editor::{Buttons, Editor, Layer, LayerTransform, Material, Scene, ToolPose};
use strata_mesh::{MeshOptions, Mesher};
use strata_render::{Camera, FrameSettings, Gpu, Renderer, render_offscreen};
use strata_viewport::{apply_changes, upload_scene};
use strata_volume::brush::Sphere;

fn gpu() -> Option<Gpu> {
    Gpu::for_tests("the mirror test")
}

fn scene() -> Scene {
    let mut scene = Scene::default();
    let mut a = Layer::new("a");
    a.volume.add(&Sphere::new(DVec3::new(20.0, 20.0, 20.0), 12.0).unwrap()).unwrap();
    let mut b = Layer::new("b");
    b.volume.add(&Sphere::new(DVec3::new(50.0, 20.0, 20.0), 8.0).unwrap()).unwrap();
    scene.layers = vec![a, b];
    scene
}

fn image(gpu: &Gpu, r: &mut Renderer) -> Vec<u8> {
    let camera = Camera { target: glam::Vec3::new(35.0, 20.0, 20.0), distance: 90.0, ..Camera::default() };
    let settings = FrameSettings { camera, grid: false, ..Default::default() };
    render_offscreen(gpu, r, 96, 64, &settings).unwrap().rgba
}

#[test]
fn change_lists_keep_a_renderer_equal_to_a_fresh_upload() {
    let Some(gpu) = gpu() else { return };
    let mut e = Editor::new(scene());
    let mut mirror = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    let mut x = 0x9e37_79b9_7f4a_7c15u64;
    let mut next = |n: u64| {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        x % n
    };
    let mut kinds = [0usize; 8];
    for step in 0..40 {
        let op = if step == 0 { 0 } else { next(8) as usize };
        kinds[op] += 1;
        match op {
            // A short stroke on one of the balls, with a budget that may leave chunks queued.
            0 | 1 => {
                let c = if next(2) == 0 { DVec3::new(20.0, 32.0, 20.0) } else { DVec3::new(50.0, 28.0, 20.0) };
                e.active_layer = usize::from(c.x > 35.0);
                let budget = Duration::from_micros(if op == 0 { 50_000 } else { 1 });
                for i in 0..4 {
                    let p = c + DVec3::new(i as f64, 0.0, 0.0);
                    let buttons = Buttons { primary: true, secondary: false };
                    let pose = ToolPose {
                        position: p,
                        orientation: DQuat::IDENTITY,
                        pressure: 1.0,
                        buttons,
                        ..ToolPose::default()
                    };
                    e.frame(&pose, budget).unwrap();
                }
                e.frame(&ToolPose::at(c, false), budget).unwrap();
            }
            2 => {
                e.undo();
            }
            3 => {
                e.redo();
            }
            4 => {
                let l = next(2) as usize;
                e.scene.layers[l].visible = !e.scene.layers[l].visible;
            }
            5 => {
                let t = LayerTransform { translation: DVec3::new(next(5) as f64, 0.0, 0.0), ..Default::default() };
                e.set_layer_transform(next(2) as usize, t, false).unwrap();
            }
            6 => {
                // A new material, and the one every vertex shows recoloured.
                e.scene.materials.push(Material { color: [0.2, 0.5, 0.9], ..e.scene.materials[0].clone() });
                e.scene.materials[0].color = [0.3 + next(7) as f32 * 0.1, 0.4, 0.5];
            }
            _ => {
                let mesher = if e.view_mesher().mesher == Mesher::MarchingCubes {
                    Mesher::DualContouring
                } else {
                    Mesher::MarchingCubes
                };
                e.set_view_mesher(MeshOptions { mesher, ..Default::default() }).unwrap();
                e.frame(&ToolPose::at(DVec3::ZERO, false), Duration::from_micros(1)).unwrap();
            }
        }
        let changes = e.take_changes();
        apply_changes(&e, &changes, &gpu.device, &gpu.queue, &mut mirror);
        let mut fresh = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
        upload_scene(&e, &gpu.device, &gpu.queue, &mut fresh);
        assert_eq!(mirror.mesh_count(), fresh.mesh_count(), "step {step} (op {op}): {changes:?}");
        assert_eq!(mirror.triangle_count(), fresh.triangle_count(), "step {step} (op {op})");
        if step % 4 == 3 || op == 6 {
            assert!(image(&gpu, &mut mirror) == image(&gpu, &mut fresh), "step {step} (op {op}): the images differ");
        }
    }
    assert!(kinds.iter().all(|&k| k > 0), "every kind of change was tried: {kinds:?}");
    // Finishing the meshing lists the rest.
    e.finish_meshing();
    let changes = e.take_changes();
    apply_changes(&e, &changes, &gpu.device, &gpu.queue, &mut mirror);
    let mut fresh = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    upload_scene(&e, &gpu.device, &gpu.queue, &mut fresh);
    assert!(image(&gpu, &mut mirror) == image(&gpu, &mut fresh), "after the last remesh");
    assert_eq!(mirror.triangle_count(), e.triangle_count() - hidden_triangles(&e));
}

/// Triangles of the layers that are hidden (the editor counts them, the renderer does not).
fn hidden_triangles(e: &Editor) -> usize {
    (0..e.scene.layers.len())
        .filter(|&i| !e.scene.layers[i].visible)
        .map(|i| e.chunk_meshes(i).iter().map(|(_, m)| m.triangle_count()).sum::<usize>())
        .sum()
}

/// The same for an editor on a streamed world: as the viewer flies (chunks streamed in and
/// dropped), digs and craters are made and undone and the meshing budget leaves work for later,
/// the renderer fed by change lists holds what a fresh upload holds.
#[test]
fn change_lists_keep_a_renderer_equal_to_a_fresh_upload_on_a_streamed_world() {
    let Some(gpu) = gpu() else { return };
    let settings =
        strata_terrain::WorldSettings { view_distance: 40.0, threads: 1, ..strata_terrain::WorldSettings::default() };
    let world = strata_terrain::World::in_memory(&strata_terrain::Recipe::with_seed(3), settings).unwrap();
    let mut e = Editor::on_world(world, Material::builtin());
    e.tool.kind = strata_editor::ToolKind::Erase;
    e.tool.radius = 4.0;
    let mut mirror = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    let mut eye = DVec3::new(0.0, 0.0, 0.0);
    let mut digs = 0;
    for step in 0..60 {
        match step % 6 {
            // Fly along x: chunks come and go.
            0 => eye.x += 24.0,
            // Dig where the ground is under the eye.
            1 | 2 => {
                if let Some(hit) = e.pick(eye + DVec3::Y * 300.0, -DVec3::Y, 600.0) {
                    e.line_stroke(hit.point, hit.point + DVec3::Z * 6.0, 1.0, Default::default()).unwrap();
                    digs += 1;
                }
            }
            3 => {
                e.undo();
            }
            _ => {}
        }
        e.stream(eye);
        let budget = Duration::from_micros(if step % 2 == 0 { 20_000 } else { 1 });
        e.frame(&ToolPose::at(eye, false), budget).unwrap();
        std::thread::sleep(Duration::from_millis(5));
        let changes = e.take_changes();
        apply_changes(&e, &changes, &gpu.device, &gpu.queue, &mut mirror);
        let mut fresh = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
        upload_scene(&e, &gpu.device, &gpu.queue, &mut fresh);
        assert_eq!(mirror.mesh_count(), fresh.mesh_count(), "step {step}: {changes:?}");
        assert_eq!(mirror.triangle_count(), fresh.triangle_count(), "step {step}");
    }
    assert!(digs > 5, "the world was dug ({digs} digs)");
    assert!(mirror.triangle_count() > 0, "the world was drawn");
}

/// `strata render` and the studio's screenshot draw a scene's shown reference images.
#[test]
fn a_headless_render_shows_the_scenes_reference_images() {
    if gpu().is_none() {
        return;
    }
    let mut s = scene();
    // A solid red PNG, in the front view's plane behind the spheres, filling the view.
    let red = {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, 2, 2);
        enc.set_color(png::ColorType::Rgb);
        let mut writer = enc.write_header().unwrap();
        writer.write_image_data(&[255, 0, 0].repeat(4)).unwrap();
        writer.finish().unwrap();
        out
    };
    let picture = strata_editor::Picture::decode(red, "red.png").unwrap();
    let bounds = Some((DVec3::new(8.0, 8.0, 8.0), DVec3::new(58.0, 32.0, 32.0)));
    let mut front = strata_editor::ReferenceImage::new("red", picture, strata_editor::ReferencePlane::Front, bounds);
    front.width = 1000.0;
    front.opacity = 1.0;
    s.references.push(front);
    s.view = strata_editor::View { target: DVec3::new(35.0, 20.0, 20.0), distance: 90.0, yaw: 0.0, pitch: 0.0 };
    let out = std::env::temp_dir().join(format!("strata-ref-render-{}.png", std::process::id()));
    let shown = |s: Scene| {
        strata_viewport::render_scene(s, &out, (64, 48), false).unwrap();
        let img = strata_editor::Picture::load(&out).unwrap();
        let (_, _, rgba) = img.shown();
        rgba[..4].to_vec()
    };
    let corner = shown(s.clone());
    assert!(corner[0] > 240 && corner[1] < 10 && corner[2] < 10, "the corner shows the picture: {corner:?}");
    s.references[0].visible = false;
    let corner = shown(s);
    assert!(corner[0] < 100, "a hidden picture is not drawn: {corner:?}");
}
