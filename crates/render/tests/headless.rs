//! Renders known scenes headless and checks the images: not blank, the object's silhouette
//! where the camera puts it, colours in range, grid lines hidden by solids above them, no
//! shading specks on thin features.
//!
//! Without a GPU adapter (not even lavapipe) these tests skip with a message, unless
//! `STRATA_REQUIRE_GPU=1` is set (CI sets it), which makes a missing adapter a failure.

use glam::{DVec3, Mat4, Vec3};
use strata_mesh::{Mesh, MeshCache};
use strata_render::{
    AxisView, Camera, FrameSettings, Gpu, Image, MeshId, MeshRef, Placement, Preview, Renderer, render_offscreen,
};

use strata_volume::brush::{Capsule, Cuboid, Sphere, Torus};
use strata_volume::tools::{Dab, grab};
use strata_volume::{ChunkKey, Volume};

fn gpu() -> Option<Gpu> {
    Gpu::for_tests("the render test")
}

/// `mesh` as the renderer reads it.
fn lend(mesh: &Mesh) -> MeshRef<'_> {
    MeshRef {
        positions: &mesh.positions,
        normals: &mesh.normals,
        materials: bytemuck::cast_slice(&mesh.materials),
        indices: &mesh.indices,
        shade: &[],
    }
}

/// Draws the chunk `key`'s mesh (relative to the chunk's origin, as mesh caches keep it).
fn upload(r: &mut Renderer, gpu: &Gpu, key: ChunkKey, mesh: &Mesh, color: [f32; 3]) {
    let placement = Placement { model: Mat4::IDENTITY, origin: key.origin_grid().as_dvec3() };
    r.upload_mesh(&gpu.device, &gpu.queue, MeshId { group: 0, key: key.0.to_array() }, lend(mesh), placement, color);
}

const W: u32 = 320;
const H: u32 = 240;
const CENTRE: Vec3 = Vec3::new(24.0, 24.0, 24.0);
const RADIUS: f32 = 12.0;

fn scene(gpu: &Gpu) -> Renderer {
    let mut volume = Volume::new();
    volume.add(&Sphere::new(CENTRE.as_dvec3(), RADIUS as f64).unwrap()).unwrap();
    let cache = MeshCache::build(&volume);
    let mut r = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    for (key, mesh) in cache.iter() {
        upload(&mut r, gpu, key, mesh, [0.72, 0.62, 0.52]);
    }
    assert_eq!(r.triangle_count(), cache.triangle_count());
    r
}

fn camera() -> Camera {
    Camera { target: CENTRE, distance: 60.0, yaw: 0.6, pitch: 0.3, fov_y: 0.8, orthographic: false }
}

fn is_background(p: [u8; 4], bg: [u8; 4]) -> bool {
    p.iter().zip(bg).all(|(a, b)| a.abs_diff(b) <= 2)
}

#[test]
fn a_sphere_renders_where_the_camera_puts_it() {
    let Some(gpu) = gpu() else { return };
    eprintln!("adapter: {:?}", gpu.info);
    let mut r = scene(&gpu);
    let settings = FrameSettings { camera: camera(), grid: false, ..Default::default() };
    let img = render_offscreen(&gpu, &mut r, W, H, &settings).unwrap();
    assert_eq!(img.rgba.len(), (4 * W * H) as usize);
    if let Ok(dir) = std::env::var("STRATA_RENDER_DUMP") {
        img.save_png(&std::path::Path::new(&dir).join("sphere.png")).unwrap();
    }
    let bg = img.pixel(0, 0);
    // The clear colour (linear 0.055, 0.06, 0.075) in sRGB.
    assert!(bg[0] > 50 && bg[0] < 80 && bg[2] > bg[0] && bg[3] == 255, "background {bg:?}");
    for (x, y) in [(W - 1, 0), (0, H - 1), (W - 1, H - 1)] {
        assert!(is_background(img.pixel(x, y), bg), "corner {x},{y}");
    }
    // The sphere is centred: the middle pixel is lit clay (red above blue), not background.
    let mid = img.pixel(W / 2, H / 2);
    assert!(!is_background(mid, bg) && mid[0] > mid[2] && mid[0] > 90, "centre {mid:?}");
    // The silhouette's area matches the projected sphere: radius r at distance d spans
    // asin(r/d) of the half field of view.
    let covered =
        (0..H).flat_map(|y| (0..W).map(move |x| (x, y))).filter(|&(x, y)| !is_background(img.pixel(x, y), bg)).count();
    let half = (0.8f32 / 2.0).tan();
    let apparent = (RADIUS / 60.0).asin().tan() / half * (H as f32 / 2.0);
    let expected = std::f32::consts::PI * apparent * apparent;
    let ratio = covered as f32 / expected;
    assert!((0.9..1.1).contains(&ratio), "covered {covered} px, expected about {expected}");
    // Shading shows form: the lit side is brighter than the shadowed side.
    let lum = |p: [u8; 4]| p[0] as u32 + p[1] as u32 + p[2] as u32;
    let row: Vec<u32> = (0..W).map(|x| img.pixel(x, H / 2)).filter(|p| !is_background(*p, bg)).map(lum).collect();
    let (lo, hi) = (row.iter().min().unwrap(), row.iter().max().unwrap());
    assert!(hi - lo > 60, "shading range {lo}..{hi}");

    // The wireframe darkens the silhouette's pixels, the grid and preview add pixels.
    let wire = render_offscreen(&gpu, &mut r, W, H, &FrameSettings { wireframe: true, ..settings }).unwrap();
    let darker = (0..H)
        .flat_map(|y| (0..W).map(move |x| (x, y)))
        .filter(|&(x, y)| lum(wire.pixel(x, y)) + 100 < lum(img.pixel(x, y)))
        .count();
    assert!(darker > 1000, "wireframe lines are drawn over the surface ({darker} pixels darker)");
    let with_grid = render_offscreen(&gpu, &mut r, W, H, &FrameSettings { grid: true, ..settings }).unwrap();
    assert_ne!(with_grid, img, "the grid is drawn");
    let brush = strata_mesh::mesh_volume_with(
        &{
            let mut v = Volume::new();
            v.add(&Sphere::new(DVec3::ZERO, 4.0).unwrap()).unwrap();
            v
        },
        strata_mesh::MeshOptions::default(),
    )
    .expect("marching cubes meshes every volume");
    let preview = Preview {
        mesh: lend(&brush),
        model: Mat4::from_translation(CENTRE + Vec3::new(0.0, 0.0, RADIUS)),
        color: [0.3, 0.6, 1.0, 0.4],
    };
    let with_preview =
        render_offscreen(&gpu, &mut r, W, H, &FrameSettings { previews: &[preview], ..settings }).unwrap();
    let bluish = |i: &Image| {
        (0..H)
            .flat_map(|y| (0..W).map(move |x| (x, y)))
            .filter(|&(x, y)| {
                let p = i.pixel(x, y);
                p[2] as u32 > p[0] as u32 + 30
            })
            .count()
    };
    assert!(bluish(&with_preview) > bluish(&img) + 100, "the translucent preview is drawn");

    // PNG round trip.
    let path = std::env::temp_dir().join(format!("strata-render-{}.png", std::process::id()));
    img.save_png(&path).unwrap();
    let decoder = png::Decoder::new(std::io::BufReader::new(std::fs::File::open(&path).unwrap()));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (W, H));
    assert_eq!(&buf[..info.buffer_size()], &img.rgba[..]);
}

#[test]
fn chunk_buffers_are_replaced_and_removed() {
    let Some(gpu) = gpu() else { return };
    let mut r = scene(&gpu);
    let n = r.mesh_count();
    assert!(n > 0);
    let uploads = r.uploads();
    let key = ChunkKey::new(1, 1, 1);
    upload(&mut r, &gpu, key, &Mesh::default(), [1.0; 3]);
    assert_eq!(r.uploads(), uploads, "an empty mesh uploads nothing");
    assert!(r.mesh_count() < n);
    r.clear_group(0);
    assert_eq!(r.mesh_count(), 0);
    let img = render_offscreen(&gpu, &mut r, 64, 48, &FrameSettings { grid: false, ..Default::default() }).unwrap();
    let bg = img.pixel(0, 0);
    assert!((0..48).all(|y| (0..64).all(|x| img.pixel(x, y) == bg)), "nothing left to draw");
    assert!(render_offscreen(&gpu, &mut r, 0, 10, &FrameSettings::default()).is_err());
}

#[test]
fn painted_materials_show_in_their_palette_colours() {
    let Some(gpu) = gpu() else { return };
    let mut volume = Volume::new();
    volume.add(&Sphere::new(CENTRE.as_dvec3(), RADIUS as f64).unwrap()).unwrap();
    // The half x < 24 red (id 1), the rest blue (id 2).
    let half = |lo: f64| {
        strata_volume::brush::Cuboid::new(DVec3::new(lo + 12.0, 24.0, 24.0), DVec3::new(12.0, 20.0, 20.0)).unwrap()
    };
    volume.paint(&half(0.0), 1).unwrap();
    volume.paint(&half(24.0), 2).unwrap();
    let cache = MeshCache::build(&volume);
    let mut r = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    let entry = |color: [f32; 3]| strata_render::PaletteEntry { color, texture: 2, scale: 8.0, roughness: 0.9 };
    r.set_palette(&gpu.queue, &[entry([0.5; 3]), entry([0.8, 0.05, 0.05]), entry([0.05, 0.05, 0.8])]);
    for (key, mesh) in cache.iter() {
        upload(&mut r, &gpu, key, mesh, [1.0; 3]);
    }
    // Looking along -z at the sphere: x grows to the right of the image.
    let cam = Camera { target: CENTRE, distance: 60.0, yaw: 0.0, pitch: 0.0, fov_y: 0.8, orthographic: false };
    let settings = FrameSettings { camera: cam, grid: false, ..Default::default() };
    let img = render_offscreen(&gpu, &mut r, W, H, &settings).unwrap();
    let (mut left, mut right) = ([0u64; 3], [0u64; 3]);
    for y in H / 2 - 10..H / 2 + 10 {
        for dx in 10..40 {
            let (l, rr) = (img.pixel(W / 2 - dx, y), img.pixel(W / 2 + dx, y));
            for k in 0..3 {
                left[k] += l[k] as u64;
                right[k] += rr[k] as u64;
            }
        }
    }
    let (red_side, blue_side) = if left[0] > right[0] { (left, right) } else { (right, left) };
    assert!(red_side[0] > 2 * red_side[2], "one side red: {red_side:?}");
    assert!(blue_side[2] > 2 * blue_side[0], "the other blue: {blue_side:?}");
}

#[test]
fn the_grid_does_not_show_through_a_box_seen_from_above() {
    let Some(gpu) = gpu() else { return };
    // A box 24 × 3 × 24 over the origin, 0.5 above the ground, so the axes and four grid lines
    // pass under it.
    let mut volume = Volume::new();
    volume.add(&Cuboid::new(DVec3::new(0.0, 2.0, 0.0), DVec3::new(12.0, 1.5, 12.0)).unwrap()).unwrap();
    let cache = MeshCache::build(&volume);
    let mut r = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    for (key, mesh) in cache.iter() {
        upload(&mut r, &gpu, key, mesh, [0.72, 0.62, 0.52]);
    }
    // From above at distance 150: lines pulled a fixed 0.0004 in clip space towards the camera
    // came about 6 units nearer, above the box's top at 3.5.
    let mut camera = Camera { target: Vec3::new(0.0, 2.0, 0.0), distance: 150.0, ..camera() };
    camera.axis_view(AxisView::Top, false);
    let without =
        render_offscreen(&gpu, &mut r, W, H, &FrameSettings { camera, grid: false, ..Default::default() }).unwrap();
    let with =
        render_offscreen(&gpu, &mut r, W, H, &FrameSettings { camera, grid: true, ..Default::default() }).unwrap();
    if let Ok(dir) = std::env::var("STRATA_RENDER_DUMP") {
        with.save_png(&std::path::Path::new(&dir).join("box-on-grid.png")).unwrap();
    }
    let bg = without.pixel(0, 0);
    // The box's pixels, less a one-pixel rim (whose pixels are part box, part ground).
    let on_box = |x: u32, y: u32| {
        (x.saturating_sub(1)..=(x + 1).min(W - 1))
            .all(|i| (y.saturating_sub(1)..=(y + 1).min(H - 1)).all(|j| !is_background(without.pixel(i, j), bg)))
    };
    let pixels = || (0..H).flat_map(|y| (0..W).map(move |x| (x, y)));
    let box_pixels = pixels().filter(|&(x, y)| on_box(x, y)).count();
    assert!(box_pixels > 1500, "the box covers {box_pixels} pixels");
    let lines_on_box = pixels().filter(|&(x, y)| on_box(x, y) && with.pixel(x, y) != without.pixel(x, y)).count();
    assert_eq!(lines_on_box, 0, "grid lines drawn over {lines_on_box} of the box's {box_pixels} pixels");
    let lines_beside = pixels().filter(|&(x, y)| with.pixel(x, y) != without.pixel(x, y)).count();
    assert!(lines_beside > 500, "the grid is drawn around the box ({lines_beside} pixels)");
}

/// Thin features laid side by side on one plane: tori of minor radius 1 and 0.7 cells, capsules
/// of radius 0.6 to 1.4, a horn tapering from 3.3 to 0.3 and three horns grabbed out of a ball.
/// Seen from above, no feature hides another, so every pixel inside a silhouette shows the top
/// of the feature it belongs to.
fn thin_features() -> Volume {
    let mut v = Volume::new();
    let y = 8.0;
    v.add(&Torus::new(DVec3::new(40.0, y, 40.0), DVec3::Y, 16.0, 1.0).unwrap()).unwrap();
    v.add(&Torus::new(DVec3::new(84.0, y, 40.0), DVec3::Y, 14.0, 0.7).unwrap()).unwrap();
    for (i, radius) in [0.6, 0.8, 1.0, 1.4].into_iter().enumerate() {
        let (z, dy) = (66.0 + 7.0 * i as f64, 0.3 * i as f64);
        v.add(&Capsule::new(DVec3::new(20.0, y, z), DVec3::new(100.0, y + dy, z + 2.0), radius).unwrap()).unwrap();
    }
    for i in 0..40 {
        let t = i as f64 / 39.0;
        let centre = DVec3::new(20.0 + 60.0 * t, y, 100.0 + 3.0 * t * t);
        v.add(&Sphere::new(centre, 3.0 * (1.0 - t) + 0.3).unwrap()).unwrap();
    }
    v.add(&Sphere::new(DVec3::new(24.0, y, 118.0), 5.0).unwrap()).unwrap();
    for (k, z) in [114.0, 118.0, 122.0].into_iter().enumerate() {
        let dab = Dab::new(DVec3::new(28.5, y, z), 1.5 + 0.5 * k as f64, 1.0).unwrap();
        grab(&mut v, &dab, DVec3::new(30.0, 0.0, (k as f64 - 1.0) * 4.0)).unwrap();
    }
    v
}

/// `mesh` with the specks' cause taken out: every triangle whose vertex normals disagree (their
/// interpolation comes shorter than 0.45 somewhere in it, or one of them lies within 84° of
/// being behind the face) gets its face normal at its three corners (new vertices); the other
/// triangles keep their vertices.
fn disagreeing_triangles_flat(mesh: &Mesh) -> (Mesh, usize) {
    let mut out = mesh.clone();
    out.indices.clear();
    let mut flat = 0;
    for t in mesh.triangles() {
        let p = t.map(|i| Vec3::from(mesh.positions[i as usize]));
        let n = t.map(|i| Vec3::from(mesh.normals[i as usize]));
        let face = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or(Vec3::Y);
        let steps = 16;
        let shortest = (0..=steps)
            .flat_map(|a| (0..=steps - a).map(move |b| (a as f32 / steps as f32, b as f32 / steps as f32)))
            .map(|(u, v)| (n[0] * (1.0 - u - v) + n[1] * u + n[2] * v).length())
            .fold(f32::MAX, f32::min);
        if shortest < 0.45 || n.iter().any(|x| x.dot(face) < 0.1) {
            flat += 1;
            for i in t {
                out.push_vertex(mesh.positions[i as usize], face.to_array(), mesh.material(i as usize), false);
            }
            let k = out.positions.len() as u32;
            out.indices.extend([k - 3, k - 2, k - 1]);
        } else {
            out.indices.extend(t);
        }
    }
    (out, flat)
}

#[test]
fn thin_features_render_without_black_specks() {
    let Some(gpu) = gpu() else { return };
    let cache = MeshCache::build(&thin_features());
    let (mut smooth, mut reference) = (
        Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb),
        Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb),
    );
    let mut flat = 0;
    for (key, mesh) in cache.iter() {
        upload(&mut smooth, &gpu, key, mesh, [1.0; 3]);
        let (fixed, n) = disagreeing_triangles_flat(mesh);
        flat += n;
        upload(&mut reference, &gpu, key, &fixed, [1.0; 3]);
    }
    // The model has the feature: triangles whose vertex normals disagree.
    assert!(flat > 50, "{flat} triangles with disagreeing vertex normals");
    let (w, h) = (640, 480);
    let lum = |p: [u8; 4]| 0.3 * p[0] as f32 + 0.59 * p[1] as f32 + 0.11 * p[2] as f32;
    let mut specks = Vec::new();
    for k in 0..8 {
        // From above, turned about the vertical and tilted a little.
        let camera = Camera {
            target: Vec3::new(60.0, 8.0, 80.0),
            distance: 150.0,
            yaw: k as f32 * 0.8,
            pitch: 1.54 - (k % 4) as f32 * 0.05,
            fov_y: 0.8,
            orthographic: false,
        };
        let settings = FrameSettings { camera, grid: false, ..Default::default() };
        let img = render_offscreen(&gpu, &mut smooth, w, h, &settings).unwrap();
        let want = render_offscreen(&gpu, &mut reference, w, h, &settings).unwrap();
        if let Ok(dir) = std::env::var("STRATA_RENDER_DUMP") {
            img.save_png(&std::path::Path::new(&dir).join(format!("thin-{k}.png"))).unwrap();
        }
        let bg = img.pixel(0, 0);
        // Pixels inside a silhouette (all eight neighbours on the surface too; both renders
        // have the same triangles, so the same coverage). Shading differs from the reference
        // where it flat-shades whole triangles and the shader blends per pixel, by up to half
        // the reference's brightness (the darkest seen: 0.48 of it); the specks were 0.3 to 0.4
        // of it on lavapipe (normals turned down, lit by the ground bounce alone) and black
        // where normalising a zero vector gives NaN.
        for y in 1..h - 1 {
            for x in 1..w - 1 {
                let inside = (x - 1..=x + 1).all(|i| (y - 1..=y + 1).all(|j| !is_background(img.pixel(i, j), bg)));
                if inside && lum(img.pixel(x, y)) < 0.4 * lum(want.pixel(x, y)) {
                    specks.push((k, x, y, img.pixel(x, y), want.pixel(x, y)));
                }
            }
        }
    }
    assert!(
        specks.is_empty(),
        "{} pixels far darker than the reference, e.g. {:?}",
        specks.len(),
        &specks[..specks.len().min(5)]
    );
}

/// A picture of two texels, red on the left, blue on the right, on a square quad `side` wide
/// facing +z at depth `z`, centred on the sphere.
fn red_blue(z: f32, side: f32, opacity: f32, rgba: &[u8]) -> strata_render::ReferenceQuad<'_> {
    let h = side / 2.0;
    let c = Vec3::new(CENTRE.x, CENTRE.y, z);
    strata_render::ReferenceQuad {
        key: 7,
        pixels: strata_render::Pixels { width: 2, height: 1, rgba },
        corners: [
            c + Vec3::new(-h, -h, 0.0),
            c + Vec3::new(h, -h, 0.0),
            c + Vec3::new(h, h, 0.0),
            c + Vec3::new(-h, h, 0.0),
        ],
        opacity,
    }
}

#[test]
fn reference_pictures_show_upright_behind_the_model_and_blend_in_front_of_it() {
    let Some(gpu) = gpu() else { return };
    let mut r = scene(&gpu);
    let mut camera = Camera { target: CENTRE, distance: 60.0, orthographic: true, ..Camera::default() };
    camera.axis_view(AxisView::Front, false);
    let rgba = [255, 0, 0, 255, 0, 0, 255, 255];
    let plain = FrameSettings { camera, grid: false, ..Default::default() };
    let model = render_offscreen(&gpu, &mut r, W, H, &plain).unwrap();
    // Behind the sphere, opaque: red on the left, blue on the right, the sphere in front.
    let behind = [red_blue(CENTRE.z - 20.0, 80.0, 1.0, &rgba)];
    let settings = FrameSettings { references: &behind, ..plain };
    let img = render_offscreen(&gpu, &mut r, W, H, &settings).unwrap();
    let (left, right, mid) = (img.pixel(10, H / 2), img.pixel(W - 10, H / 2), img.pixel(W / 2, H / 2));
    assert!(left[0] > 240 && left[1] < 10 && left[2] < 10, "left {left:?}");
    assert!(right[2] > 240 && right[0] < 10 && right[1] < 10, "right {right:?}");
    assert_eq!(mid, model.pixel(W / 2, H / 2), "the model hides the picture behind it");
    // The same picture in front at half opacity: over the model, a mix of the two.
    let in_front = [red_blue(CENTRE.z + 20.0, 80.0, 0.5, &rgba)];
    let settings = FrameSettings { references: &in_front, ..plain };
    let img = render_offscreen(&gpu, &mut r, W, H, &settings).unwrap();
    let (over, under) = (img.pixel(W / 4, H / 2), model.pixel(W / 4, H / 2));
    assert!(over[0] > under[0] + 60 && over[0] < 240, "half red: blended {over:?} over {under:?}");
    assert_ne!(img.pixel(W / 2 - 20, H / 2), model.pixel(W / 2 - 20, H / 2), "the sphere is tinted");
    assert_eq!(r.picture_uploads(), 1, "the picture was uploaded once for both frames");
    // Invisible (opacity 0) and damaged quads draw nothing.
    let none = [red_blue(CENTRE.z + 20.0, 80.0, 0.0, &rgba), red_blue(f32::NAN, 80.0, 1.0, &rgba)];
    let settings = FrameSettings { references: &none, ..plain };
    let img = render_offscreen(&gpu, &mut r, W, H, &settings).unwrap();
    assert_eq!(img.rgba, model.rgba);
}
