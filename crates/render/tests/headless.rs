//! Renders a known scene headless and checks the image: not blank, the object's silhouette
//! where the camera puts it, colours in range.
//!
//! Without a GPU adapter (not even lavapipe) these tests skip with a message, unless
//! `STRATA_REQUIRE_GPU=1` is set (CI sets it), which makes a missing adapter a failure.

use glam::{DVec3, Mat4, Vec3};
use strata_mesh::MeshCache;
use strata_render::{Camera, FrameSettings, Gpu, Image, Preview, Renderer, render_offscreen};

use strata_volume::Volume;
use strata_volume::brush::Sphere;

fn gpu() -> Option<Gpu> {
    match Gpu::headless() {
        Ok(g) => Some(g),
        Err(e) if std::env::var("STRATA_REQUIRE_GPU").is_ok_and(|v| v == "1") => {
            panic!("STRATA_REQUIRE_GPU=1 but no adapter: {e}")
        }
        Err(e) => {
            eprintln!("skipping the render test: {e}");
            None
        }
    }
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
        r.upload_chunk(&gpu.device, &gpu.queue, 0, key, mesh, Mat4::IDENTITY, [0.72, 0.62, 0.52]);
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
    let brush = strata_mesh::mesh_volume(&{
        let mut v = Volume::new();
        v.add(&Sphere::new(DVec3::ZERO, 4.0).unwrap()).unwrap();
        v
    });
    let preview = Preview {
        mesh: &brush,
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
    let n = r.chunk_count();
    assert!(n > 0);
    let uploads = r.uploads();
    let key = strata_volume::ChunkKey::new(1, 1, 1);
    r.upload_chunk(&gpu.device, &gpu.queue, 0, key, &strata_mesh::Mesh::default(), Mat4::IDENTITY, [1.0; 3]);
    assert_eq!(r.uploads(), uploads, "an empty mesh uploads nothing");
    assert!(r.chunk_count() < n);
    r.clear_layer(0);
    assert_eq!(r.chunk_count(), 0);
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
        r.upload_chunk(&gpu.device, &gpu.queue, 0, key, mesh, Mat4::IDENTITY, [1.0; 3]);
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
