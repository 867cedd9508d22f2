//! A headless GPU context and offscreen rendering to an image.

use std::path::Path;

use thiserror::Error;

use crate::renderer::{DEPTH_FORMAT, FrameSettings, MeshId, MeshRef, PaletteEntry, Placement, Renderer};

/// Why rendering could not happen.
#[derive(Debug, Error)]
pub enum RenderError {
    /// No GPU adapter (not even a software one such as lavapipe) was found.
    #[error("no GPU adapter found ({0}); install a Vulkan driver, e.g. Debian's mesa-vulkan-drivers")]
    NoAdapter(String),
    /// The adapter refused to create a device.
    #[error("the GPU adapter refused a device: {0}")]
    NoDevice(String),
    /// Reading the image back failed.
    #[error("reading the rendered image back failed: {0}")]
    Readback(String),
    /// A size of zero or beyond the adapter's limits.
    #[error("image size {0}×{1} is not renderable (1 to {2} pixels per side)")]
    BadSize(u32, u32, u32),
    /// Writing the PNG failed.
    #[error("writing the PNG failed: {0}")]
    Png(String),
    /// File system error.
    #[error(transparent)]
    Io(#[from] std::io::Error),
}

/// A device and queue without any window.
#[derive(Debug)]
pub struct Gpu {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// What the adapter is (name, backend, device type).
    pub info: wgpu::AdapterInfo,
    /// The adapter (what it can do: limits, downlevel capabilities).
    pub adapter: wgpu::Adapter,
    max_texture: u32,
}

impl Gpu {
    /// [`Gpu::headless`] for a test suite that needs a GPU: `None` (the suite skips, saying
    /// which) where there is no adapter, unless `STRATA_REQUIRE_GPU=1` (CI sets it), where a
    /// missing adapter panics: a CI run never passes by skipping.
    pub fn for_tests(suite: &str) -> Option<Gpu> {
        match Gpu::headless() {
            Ok(g) => Some(g),
            Err(e) if std::env::var("STRATA_REQUIRE_GPU").is_ok_and(|v| v == "1") => {
                panic!("STRATA_REQUIRE_GPU=1 but no adapter: {e}")
            }
            Err(e) => {
                eprintln!("skipping {suite}: {e}");
                None
            }
        }
    }

    /// A headless context on the first adapter found (`WGPU_BACKEND` etc. are honoured).
    pub fn headless() -> Result<Gpu, RenderError> {
        Gpu::headless_with(wgpu::Features::empty())
    }

    /// [`Gpu::headless`] with those of `wanted` features the adapter has (for example
    /// timestamp queries, for timing the GPU's own work).
    pub fn headless_with(wanted: wgpu::Features) -> Result<Gpu, RenderError> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            ..Default::default()
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        let limits = wgpu::Limits::downlevel_defaults().using_resolution(adapter.limits());
        let max_texture = limits.max_texture_dimension_2d;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("strata headless"),
            required_features: wanted & adapter.features(),
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|e| RenderError::NoDevice(e.to_string()))?;
        Ok(Gpu { device, queue, info: adapter.get_info(), adapter, max_texture })
    }

    /// The largest image side this device renders.
    pub fn max_size(&self) -> u32 {
        self.max_texture
    }
}

/// An RGBA8 image (sRGB), rows top to bottom.
#[derive(Clone, Debug, PartialEq)]
pub struct Image {
    /// Pixels per row.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// `4 · width · height` bytes.
    pub rgba: Vec<u8>,
}

impl Image {
    /// The pixel at `(x, y)` (y down).
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = 4 * (y as usize * self.width as usize + x as usize);
        [self.rgba[i], self.rgba[i + 1], self.rgba[i + 2], self.rgba[i + 3]]
    }

    /// Encodes as PNG (the `png` crate's fast compression: a fraction of the balanced level's
    /// time for slightly larger files) and writes it atomically
    /// ([`strata_files::write_atomically`]).
    pub fn save_png(&self, path: &Path) -> Result<(), RenderError> {
        let mut bytes = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut bytes, self.width, self.height);
            enc.set_color(png::ColorType::Rgba);
            enc.set_depth(png::BitDepth::Eight);
            enc.set_compression(png::Compression::Fast);
            let mut w = enc.write_header().map_err(|e| RenderError::Png(e.to_string()))?;
            w.write_image_data(&self.rgba).map_err(|e| RenderError::Png(e.to_string()))?;
        }
        strata_files::write_atomically::<RenderError>(path, |f| Ok(std::io::Write::write_all(f, &bytes)?))
    }
}

/// Renders one frame of `renderer` into a `width × height` offscreen texture and reads it back.
pub fn render_offscreen(
    gpu: &Gpu,
    renderer: &mut Renderer,
    width: u32,
    height: u32,
    settings: &FrameSettings<'_>,
) -> Result<Image, RenderError> {
    if width == 0 || height == 0 || width > gpu.max_texture || height > gpu.max_texture {
        return Err(RenderError::BadSize(width, height, gpu.max_texture));
    }
    let device = &gpu.device;
    let size = wgpu::Extent3d { width, height, depth_or_array_layers: 1 };
    let texture = |format, usage, label| {
        device.create_texture(&wgpu::TextureDescriptor {
            label: Some(label),
            size,
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage,
            view_formats: &[],
        })
    };
    let color = texture(
        wgpu::TextureFormat::Rgba8UnormSrgb,
        wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        "offscreen colour",
    );
    let depth = texture(DEPTH_FORMAT, wgpu::TextureUsages::RENDER_ATTACHMENT, "offscreen depth");
    let color_view = color.create_view(&Default::default());
    let depth_view = depth.create_view(&Default::default());
    renderer.render(device, &gpu.queue, &color_view, &depth_view, (width, height), settings);
    // Rows of the read-back buffer are padded to 256 bytes.
    let row = 4 * width;
    let padded = row.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("offscreen readback"),
        size: padded as u64 * height as u64,
        usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let mut encoder = device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("readback") });
    encoder.copy_texture_to_buffer(
        wgpu::TexelCopyTextureInfo {
            texture: &color,
            mip_level: 0,
            origin: wgpu::Origin3d::ZERO,
            aspect: wgpu::TextureAspect::All,
        },
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded),
                rows_per_image: Some(height),
            },
        },
        size,
    );
    gpu.queue.submit([encoder.finish()]);
    let slice = buffer.slice(..);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| RenderError::Readback(e.to_string()))?;
    rx.recv().map_err(|e| RenderError::Readback(e.to_string()))?.map_err(|e| RenderError::Readback(e.to_string()))?;
    let data = slice.get_mapped_range().map_err(|e| RenderError::Readback(e.to_string()))?;
    let mut rgba = Vec::with_capacity((row * height) as usize);
    for r in 0..height as usize {
        let start = r * padded as usize;
        rgba.extend_from_slice(&data[start..start + row as usize]);
    }
    drop(data);
    buffer.unmap();
    Ok(Image { width, height, rgba })
}

/// One mesh for [`screenshot`]: what [`Renderer::upload_mesh`] takes.
#[derive(Clone, Copy, Debug)]
pub struct DrawMesh<'a> {
    /// Its name (unique among the meshes of one screenshot).
    pub id: MeshId,
    /// The triangles.
    pub mesh: MeshRef<'a>,
    /// Where they are drawn.
    pub placement: Placement,
    /// The tint multiplying its materials' colours.
    pub color: [f32; 3],
}

/// Renders `meshes` with `palette` as `settings` say into a `size` PNG at `out`, on a headless
/// GPU (no window, no display): the one screenshot path of the studio's `--screenshot` and
/// `strata render`. Returns the adapter's name.
pub fn screenshot<'a>(
    meshes: impl IntoIterator<Item = DrawMesh<'a>>,
    palette: &[PaletteEntry],
    settings: &FrameSettings<'_>,
    size: (u32, u32),
    out: &Path,
) -> Result<String, RenderError> {
    let gpu = Gpu::headless()?;
    let mut renderer = Renderer::new(&gpu.device, wgpu::TextureFormat::Rgba8UnormSrgb);
    renderer.set_palette(&gpu.queue, palette);
    for m in meshes {
        renderer.upload_mesh(&gpu.device, &gpu.queue, m.id, m.mesh, m.placement, m.color);
    }
    let image = render_offscreen(&gpu, &mut renderer, size.0, size.1, settings)?;
    image.save_png(out)?;
    Ok(gpu.info.name.clone())
}
