//! GPU meshing on the viewport's road: a renderer fed by change lists whose caller-meshed
//! chunks are meshed on the GPU and drawn from where they were made draws the same image as
//! one the CPU's meshes are uploaded to, through strokes, undo, hidden and moved layers, paint,
//! seams with finer chunks (split on the GPU) and masks (the layer goes back to the CPU); a
//! device that fails while meshing is an error, not a panic.
//!
//! Without a GPU adapter (not even lavapipe) the tests skip with a message, unless
//! `STRATA_REQUIRE_GPU=1` is set (CI sets it).

use std::time::Duration;

use glam::{DQuat, DVec3};
use strata_editor::{Buttons, Editor, Layer, LayerTransform, Scene, ToolKind, ToolPose};
use strata_render::{Camera, FrameSettings, Gpu, Renderer, render_offscreen};
use strata_viewport::{GpuMeshing, apply_changes, apply_changes_with};
use strata_volume::Level;
use strata_volume::brush::{Cuboid, Sphere};

fn gpu() -> Option<Gpu> {
    Gpu::for_tests("the GPU meshing viewport test")
}

fn scene() -> Scene {
    let mut scene = Scene::default();
    let mut a = Layer::new("a");
    a.volume.add(&Sphere::new(DVec3::new(20.0, 20.0, 20.0), 12.0).unwrap()).unwrap();
    a.volume.paint(&Cuboid::new(DVec3::new(26.0, 20.0, 20.0), DVec3::new(6.0, 20.0, 20.0)).unwrap(), 1).unwrap();
    let mut b = Layer::new("b");
    b.volume.add(&Sphere::new(DVec3::new(50.0, 20.0, 20.0), 8.0).unwrap()).unwrap();
    scene.layers = vec![a, b];
    scene
}

fn image(gpu: &Gpu, r: &mut Renderer, wireframe: bool) -> Vec<u8> {
    let camera = Camera { target: glam::Vec3::new(35.0, 20.0, 20.0), distance: 90.0, ..Camera::default() };
    let settings = FrameSettings { camera, grid: false, wireframe, ..Default::default() };
    render_offscreen(gpu, r, 128, 80, &settings).unwrap().rgba
}

/// A close look, wireframe on, at the top of the first ball (where the strokes and the finer
/// chunks are): every triangle's edges show.
fn close_up(gpu: &Gpu, r: &mut Renderer) -> Vec<u8> {
    let camera = Camera { target: glam::Vec3::new(20.0, 31.0, 20.0), distance: 16.0, pitch: 1.2, ..Camera::default() };
    let settings = FrameSettings { camera, grid: false, wireframe: true, ..Default::default() };
    render_offscreen(gpu, r, 256, 256, &settings).unwrap().rgba
}

/// Pixels that differ by more than 2 in some channel (the GPU places vertices in f32, the
/// CPU in f64 then rounds: an edge pixel may flip).
fn differing(a: &[u8], b: &[u8]) -> usize {
    a.chunks_exact(4).zip(b.chunks_exact(4)).filter(|(p, q)| p.iter().zip(*q).any(|(x, y)| x.abs_diff(*y) > 2)).count()
}

fn stroke(e: &mut Editor, at: DVec3) {
    for i in 0..4 {
        let pose = ToolPose {
            position: at + DVec3::new(i as f64, 0.0, 0.0),
            orientation: DQuat::IDENTITY,
            pressure: 1.0,
            buttons: Buttons { primary: true, secondary: false },
            ..ToolPose::default()
        };
        e.frame(&pose, Duration::from_millis(50)).unwrap();
    }
    e.frame(&ToolPose::at(at, false), Duration::from_millis(50)).unwrap();
}

/// The steps both tests take first: nothing, a stroke, an erasing stroke, an undo. `false` for
/// a later step.
fn first_steps(e: &mut Editor, step: usize) -> bool {
    match step {
        0 => {}
        1 => stroke(e, DVec3::new(20.0, 32.0, 20.0)),
        2 => {
            e.tool.kind = ToolKind::Erase;
            stroke(e, DVec3::new(50.0, 28.0, 20.0));
            e.tool.kind = ToolKind::Add;
        }
        3 => {
            e.undo();
        }
        _ => return false,
    }
    true
}

/// Applies both editors' change lists: the GPU's through GPU meshing, the CPU's uploaded.
fn apply_both(
    gpu: &Gpu,
    (on_gpu, drawn, meshing): (&mut Editor, &mut Renderer, &mut GpuMeshing),
    (on_cpu, want): (&mut Editor, &mut Renderer),
) {
    let changes = on_gpu.take_changes();
    apply_changes_with(on_gpu, &changes, &gpu.device, &gpu.queue, drawn, Some(meshing)).unwrap();
    let changes = on_cpu.take_changes();
    apply_changes(on_cpu, &changes, &gpu.device, &gpu.queue, want);
}

/// The renderer kept up to date by change lists shows exactly what one given every chunk anew
/// shows (no chunk stale: seams left by undone finer chunks, for one).
fn assert_like_a_full_remesh(gpu: &Gpu, editor: &Editor, drawn: &mut Renderer, step: usize) {
    let mut fresh = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    let mut fresh_meshing = GpuMeshing::new(&gpu.adapter, &gpu.device).unwrap();
    let all = strata_editor::ChangeList { full: true, ..Default::default() };
    apply_changes_with(editor, &all, &gpu.device, &gpu.queue, &mut fresh, Some(&mut fresh_meshing)).unwrap();
    assert!(
        close_up(gpu, drawn) == close_up(gpu, &mut fresh),
        "step {step}: the incremental GPU meshes differ from a full remesh"
    );
}

#[test]
fn gpu_meshed_chunks_draw_what_the_cpus_meshes_draw() {
    let Some(gpu) = gpu() else { return };
    let mut meshing = GpuMeshing::new(&gpu.adapter, &gpu.device).unwrap();
    // The GPU's editor and renderer, and the CPU's.
    let mut on_gpu = Editor::new(scene());
    on_gpu.set_gpu_meshing(true);
    let mut on_cpu = Editor::new(scene());
    let mut drawn = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    let mut want = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    let mut steps = 0;
    for step in 0..9 {
        for e in [&mut on_gpu, &mut on_cpu] {
            match step {
                _ if first_steps(e, step) => {}
                4 => e.scene.layers[1].visible = false,
                5 => {
                    e.scene.layers[1].visible = true;
                    let t = LayerTransform { translation: DVec3::new(3.0, 1.0, 0.0), ..Default::default() };
                    e.set_layer_transform(1, t, false).unwrap();
                }
                6 => {
                    // Finer chunks: the coarser blocks facing them have seams, split on the GPU.
                    e.active_layer = 0;
                    e.tool.kind = ToolKind::Detail;
                    e.tool.detail_level = Level::new(1).unwrap();
                    let r = e.tool.radius;
                    e.tool.radius = 3.0;
                    stroke(e, DVec3::new(20.0, 32.0, 20.0));
                    e.tool.radius = r;
                    e.tool.kind = ToolKind::Add;
                    assert!(!e.scene.layers[0].volume.single_level(), "the layer mixes levels");
                }
                7 => {
                    // Undoing the finer chunks: the coarser neighbours on every side lose their
                    // seams (none may keep triangles split at points that are gone).
                    e.undo();
                    assert!(e.scene.layers[0].volume.single_level(), "back to one level");
                    stroke(e, DVec3::new(14.0, 30.0, 22.0));
                }
                _ => {
                    // A mask: the layer goes back to the CPU, which shades what it holds.
                    e.tool.kind = ToolKind::Mask;
                    stroke(e, DVec3::new(20.0, 32.0, 20.0));
                    e.tool.kind = ToolKind::Add;
                }
            }
            e.finish_meshing();
        }
        apply_both(&gpu, (&mut on_gpu, &mut drawn, &mut meshing), (&mut on_cpu, &mut want));
        // Batches are kept while shown, and repacked before they hold four times what is shown.
        let resident = meshing.resident_blocks();
        assert!(
            resident <= 4 * drawn.indirect_count(),
            "step {step}: {resident} blocks held for {}",
            drawn.indirect_count()
        );
        assert_eq!(drawn.mesh_count(), want.mesh_count(), "step {step}: the chunks shown");
        match step {
            6 => assert!(drawn.mesh_count() == drawn.indirect_count(), "the blocks with seams were split on the GPU"),
            8 => assert!(!on_gpu.meshed_by_caller(0) && on_gpu.meshed_by_caller(1), "the masked layer is the CPU's"),
            _ => assert!(drawn.indirect_count() > 0 && on_gpu.meshed_by_caller(0)),
        }
        for wireframe in [false, true] {
            let (a, b) = (image(&gpu, &mut drawn, wireframe), image(&gpu, &mut want, wireframe));
            let d = differing(&a, &b);
            assert!(d * 1000 <= a.len() / 4, "step {step} (wireframe {wireframe}): {d} pixels differ");
            assert!(a.chunks_exact(4).any(|p| p[0] > 60), "step {step}: something was drawn");
        }
        assert_like_a_full_remesh(&gpu, &on_gpu, &mut drawn, step);
        steps += 1;
    }
    assert_eq!(steps, 9);
    // Strokes all around the first ball replace most chunks of the first batch: the few left of
    // it are meshed again into a new one, so the old buffers go.
    for k in 0..12 {
        let a = k as f64 * std::f64::consts::TAU / 12.0;
        let at = DVec3::new(20.0 + 13.0 * a.cos(), 20.0 + 13.0 * a.sin(), 20.0 + if k % 2 == 0 { 6.0 } else { -6.0 });
        for e in [&mut on_gpu, &mut on_cpu] {
            e.active_layer = 0;
            stroke(e, at);
            e.finish_meshing();
        }
        apply_both(&gpu, (&mut on_gpu, &mut drawn, &mut meshing), (&mut on_cpu, &mut want));
        let resident = meshing.resident_blocks();
        assert!(resident <= 4 * drawn.indirect_count(), "stroke {k}: {resident} blocks held");
    }
    assert!(meshing.repacked() > 0, "a sparse batch was meshed again");
    let (a, b) = (image(&gpu, &mut drawn, false), image(&gpu, &mut want, false));
    assert!(differing(&a, &b) * 1000 <= a.len() / 4, "after the strokes around the ball");
}

#[test]
fn a_device_lost_while_meshing_is_an_error_and_the_cpu_takes_over() {
    let Some(gpu) = gpu() else { return };
    let Some(lost) = Gpu::for_tests("the lost-device test") else { return };
    let mut meshing = GpuMeshing::new(&lost.adapter, &lost.device).unwrap();
    let mut e = Editor::new(scene());
    e.set_gpu_meshing(true);
    e.finish_meshing();
    let mut r = Renderer::new(&lost.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    lost.device.destroy();
    let changes = e.take_changes();
    let failed = apply_changes_with(&e, &changes, &lost.device, &lost.queue, &mut r, Some(&mut meshing));
    assert!(failed.is_err(), "meshing on a destroyed device: {failed:?}");
    // The CPU takes over: every chunk meshed again and uploaded on a working device.
    e.set_gpu_meshing(false);
    e.finish_meshing();
    let mut r = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    let changes = e.take_changes();
    apply_changes(&e, &changes, &gpu.device, &gpu.queue, &mut r);
    assert!(r.mesh_count() > 0 && r.indirect_count() == 0 && r.triangle_count() > 0);
}

/// Dual contouring under GPU meshing: made and drawn on the GPU, the same picture as the CPU's
/// dual contouring through strokes, erasing and undo, at one level and then across levels
/// (finer chunks made, sculpted across, undone back to one level: the quads stay joined across
/// levels, as the CPU's stay); the renderer kept by change lists equals one given every chunk
/// anew.
#[test]
fn gpu_dual_contouring_draws_what_the_cpus_draws() {
    use strata_mesh::{MeshOptions, Mesher};
    let Some(gpu) = gpu() else { return };
    let mut meshing = GpuMeshing::new(&gpu.adapter, &gpu.device).unwrap();
    let dual = MeshOptions::new(Mesher::DualContouring);
    let mut on_gpu = Editor::new(scene());
    on_gpu.set_view_mesher(dual).unwrap();
    on_gpu.set_gpu_meshing(true);
    let mut on_cpu = Editor::new(scene());
    on_cpu.set_view_mesher(dual).unwrap();
    let mut drawn = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    let mut want = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    for step in 0..9 {
        for e in [&mut on_gpu, &mut on_cpu] {
            match step {
                _ if first_steps(e, step) => {}
                4 => stroke(e, DVec3::new(8.0, 20.0, 26.0)),
                5 => {
                    // Finer chunks: this layer's levels mix.
                    e.active_layer = 0;
                    e.tool.kind = ToolKind::Detail;
                    e.tool.detail_level = Level::new(1).unwrap();
                    e.tool.radius = 3.0;
                    stroke(e, DVec3::new(20.0, 32.0, 20.0));
                    e.tool.kind = ToolKind::Add;
                    assert!(!e.scene.layers[0].volume.single_level(), "the layer mixes levels");
                }
                // Sculpting across the seams between the levels.
                6 => stroke(e, DVec3::new(18.0, 31.5, 21.0)),
                7 => {
                    e.tool.kind = ToolKind::Erase;
                    stroke(e, DVec3::new(21.0, 31.0, 19.0));
                    e.tool.kind = ToolKind::Add;
                }
                _ => {
                    // Back to one level: the quads stay joined across levels.
                    for _ in 0..3 {
                        e.undo();
                    }
                    assert!(e.scene.layers[0].volume.single_level(), "back to one level");
                }
            }
            e.finish_meshing();
        }
        apply_both(&gpu, (&mut on_gpu, &mut drawn, &mut meshing), (&mut on_cpu, &mut want));
        assert!(on_gpu.meshed_by_caller(0) && on_gpu.caller_dual(0), "step {step}");
        assert_eq!(on_gpu.caller_dual_across_levels(0), step >= 5, "step {step}: joined across levels");
        assert!(drawn.indirect_count() > 0 && drawn.triangle_count() == 0, "step {step}: all on the GPU");
        let (a, b) = (image(&gpu, &mut drawn, false), image(&gpu, &mut want, false));
        let d = differing(&a, &b);
        assert!(d * 1000 <= a.len() / 4, "step {step}: {d} pixels differ");
        assert_like_a_full_remesh(&gpu, &on_gpu, &mut drawn, step);
    }
}
