//! Reference pictures: a picture on a quad in the world, drawn after the opaque surfaces and
//! the grid and before the translucent previews, blended by its opacity, depth-tested but not writing depth
//! (the model in front of a picture hides it; a picture hides nothing). Pictures overlapping
//! on screen are drawn farthest first.
//!
//! Each picture is a texture kept by the caller's key (a hash of the picture) across frames, so
//! it is uploaded once, with its mip chain made on the CPU (a 2×2 box filter in linear light,
//! weighted by alpha, so smaller levels neither darken nor fringe) so a large
//! picture seen small does not shimmer; pictures larger than the device allows are halved until
//! they fit. Textures of pictures no longer drawn are dropped once more than
//! [`KEPT_TEXTURES`] are held.

use std::collections::HashMap;

use bytemuck::{Pod, Zeroable};
use glam::Vec3;
use wgpu::util::DeviceExt;

/// Textures kept for pictures not drawn in the current frame, at most (a hidden picture shown
/// again is not uploaded anew).
pub const KEPT_TEXTURES: usize = 16;

/// A picture's pixels: straight-alpha sRGB RGBA bytes, rows from the top.
#[derive(Clone, Copy, Debug)]
pub struct Pixels<'a> {
    /// Columns.
    pub width: u32,
    /// Rows.
    pub height: u32,
    /// `width × height × 4` bytes.
    pub rgba: &'a [u8],
}

/// One reference picture to draw.
#[derive(Clone, Copy, Debug)]
pub struct ReferenceQuad<'a> {
    /// The picture's name for the texture cache: the same key, the same pixels.
    pub key: u64,
    /// The pixels (uploaded the first time the key is seen).
    pub pixels: Pixels<'a>,
    /// World corners: the picture's bottom left, bottom right, top right and top left.
    pub corners: [Vec3; 4],
    /// 0 transparent to 1 opaque.
    pub opacity: f32,
}

impl ReferenceQuad<'_> {
    /// Whether it can be drawn: finite corners, a visible opacity and pixels that match their
    /// size.
    fn drawable(&self) -> bool {
        let p = &self.pixels;
        self.corners.iter().all(|c| c.is_finite())
            && self.opacity > 0.0
            && self.opacity.is_finite()
            && p.width > 0
            && p.height > 0
            && p.rgba.len() as u64 == p.width as u64 * p.height as u64 * 4
    }
}

#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
struct ReferenceVertex {
    position: [f32; 3],
    uv: [f32; 2],
    opacity: f32,
}

const ATTRIBUTES: [wgpu::VertexAttribute; 3] = wgpu::vertex_attr_array![0 => Float32x3, 1 => Float32x2, 2 => Float32];

/// The pipeline, the textures and this frame's quads.
pub(crate) struct ReferencePass {
    pipeline: wgpu::RenderPipeline,
    layout: wgpu::BindGroupLayout,
    sampler: wgpu::Sampler,
    textures: HashMap<u64, wgpu::BindGroup>,
    /// This frame's vertices and indices, and the texture key of each quad, in draw order.
    frame: Option<(wgpu::Buffer, wgpu::Buffer, Vec<u64>)>,
    uploads: u64,
}

impl ReferencePass {
    /// The pipeline for a colour target of `color_format`, reading the frame's uniforms through
    /// `frame_layout` (group 0) from `shader`'s `vs_reference` and `fs_reference`.
    pub(crate) fn new(
        device: &wgpu::Device,
        shader: &wgpu::ShaderModule,
        frame_layout: &wgpu::BindGroupLayout,
        color_format: wgpu::TextureFormat,
    ) -> Self {
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("strata reference picture"),
            entries: &[
                wgpu::BindGroupLayoutEntry {
                    binding: 0,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Texture {
                        sample_type: wgpu::TextureSampleType::Float { filterable: true },
                        view_dimension: wgpu::TextureViewDimension::D2,
                        multisampled: false,
                    },
                    count: None,
                },
                wgpu::BindGroupLayoutEntry {
                    binding: 1,
                    visibility: wgpu::ShaderStages::FRAGMENT,
                    ty: wgpu::BindingType::Sampler(wgpu::SamplerBindingType::Filtering),
                    count: None,
                },
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("strata reference"),
            bind_group_layouts: &[Some(frame_layout), Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("strata reference"),
            layout: Some(&pipeline_layout),
            vertex: wgpu::VertexState {
                module: shader,
                entry_point: Some("vs_reference"),
                compilation_options: Default::default(),
                buffers: &[Some(wgpu::VertexBufferLayout {
                    array_stride: std::mem::size_of::<ReferenceVertex>() as u64,
                    step_mode: wgpu::VertexStepMode::Vertex,
                    attributes: &ATTRIBUTES,
                })],
            },
            // Both faces: a picture seen from behind shows mirrored, as a sheet of glass would.
            primitive: wgpu::PrimitiveState { topology: wgpu::PrimitiveTopology::TriangleList, ..Default::default() },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: crate::DEPTH_FORMAT,
                depth_write_enabled: Some(false),
                depth_compare: Some(wgpu::CompareFunction::LessEqual),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: Default::default(),
            fragment: Some(wgpu::FragmentState {
                module: shader,
                entry_point: Some("fs_reference"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format: color_format,
                    blend: Some(wgpu::BlendState::ALPHA_BLENDING),
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("strata reference sampler"),
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            ..Default::default()
        });
        ReferencePass { pipeline, layout, sampler, textures: HashMap::new(), frame: None, uploads: 0 }
    }

    /// Pictures uploaded since creation.
    pub(crate) fn uploads(&self) -> u64 {
        self.uploads
    }

    /// Uploads the pictures not yet held and this frame's quads, farthest from `eye` first.
    pub(crate) fn prepare(
        &mut self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        quads: &[ReferenceQuad<'_>],
        eye: Vec3,
    ) {
        let mut order: Vec<&ReferenceQuad<'_>> = quads.iter().filter(|q| q.drawable()).collect();
        let depth = |q: &ReferenceQuad<'_>| (q.corners.iter().copied().sum::<Vec3>() * 0.25 - eye).length_squared();
        order.sort_by(|a, b| depth(b).total_cmp(&depth(a)));
        for q in &order {
            if !self.textures.contains_key(&q.key) {
                let group = self.upload(device, queue, q.pixels);
                self.textures.insert(q.key, group);
                self.uploads += 1;
            }
        }
        if self.textures.len() > KEPT_TEXTURES {
            self.textures.retain(|k, _| order.iter().any(|q| q.key == *k));
        }
        if order.is_empty() {
            self.frame = None;
            return;
        }
        let uv = [[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]];
        let mut vertices = Vec::with_capacity(order.len() * 4);
        let mut indices = Vec::with_capacity(order.len() * 6);
        for (i, q) in order.iter().enumerate() {
            let base = i as u32 * 4;
            indices.extend([0, 1, 2, 0, 2, 3].map(|k| base + k));
            for (c, uv) in q.corners.iter().zip(uv) {
                vertices.push(ReferenceVertex { position: c.to_array(), uv, opacity: q.opacity.min(1.0) });
            }
        }
        let vb = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("reference vertices"),
            contents: bytemuck::cast_slice(&vertices),
            usage: wgpu::BufferUsages::VERTEX,
        });
        let ib = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("reference indices"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });
        self.frame = Some((vb, ib, order.iter().map(|q| q.key).collect()));
    }

    /// A texture of `pixels` with its mip chain (halved first until it fits the device), bound
    /// for the fragment shader.
    fn upload(&self, device: &wgpu::Device, queue: &wgpu::Queue, pixels: Pixels<'_>) -> wgpu::BindGroup {
        let limit = device.limits().max_texture_dimension_2d.max(1);
        let mut levels = mip_chain(pixels);
        while levels.len() > 1 && levels[0].0.max(levels[0].1) > limit {
            levels.remove(0);
        }
        let (w, h, _) = levels[0];
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("strata reference picture"),
            size: wgpu::Extent3d { width: w, height: h, depth_or_array_layers: 1 },
            mip_level_count: levels.len() as u32,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8UnormSrgb,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        for (mip, (w, h, texels)) in levels.iter().enumerate() {
            queue.write_texture(
                wgpu::TexelCopyTextureInfo {
                    texture: &texture,
                    mip_level: mip as u32,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                texels,
                wgpu::TexelCopyBufferLayout { offset: 0, bytes_per_row: Some(w * 4), rows_per_image: Some(*h) },
                wgpu::Extent3d { width: *w, height: *h, depth_or_array_layers: 1 },
            );
        }
        let view = texture.create_view(&Default::default());
        device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("strata reference picture"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry { binding: 0, resource: wgpu::BindingResource::TextureView(&view) },
                wgpu::BindGroupEntry { binding: 1, resource: wgpu::BindingResource::Sampler(&self.sampler) },
            ],
        })
    }

    /// Records this frame's quads into `pass` (`frame` the frame's group 0).
    pub(crate) fn draw(&self, pass: &mut wgpu::RenderPass<'_>, frame: &wgpu::BindGroup) {
        let Some((vb, ib, keys)) = &self.frame else { return };
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, frame, &[]);
        pass.set_vertex_buffer(0, vb.slice(..));
        pass.set_index_buffer(ib.slice(..), wgpu::IndexFormat::Uint32);
        for (i, key) in keys.iter().enumerate() {
            let Some(group) = self.textures.get(key) else { continue };
            pass.set_bind_group(1, group, &[]);
            let first = i as u32 * 6;
            pass.draw_indexed(first..first + 6, 0, 0..1);
        }
    }
}

/// sRGB byte to linear light.
fn to_linear(c: u8) -> f32 {
    let c = c as f32 / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Linear light to an sRGB byte.
fn to_srgb(l: f32) -> u8 {
    let c = if l <= 0.003_130_8 { l * 12.92 } else { 1.055 * l.powf(1.0 / 2.4) - 0.055 };
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
}

/// `pixels` and each half-size level below them down to 1 × 1 (a 2×2 box filter, an odd row or
/// column folded into the last; colours averaged in linear light weighted by their alpha, alpha
/// plainly), as (width, height, bytes).
fn mip_chain(pixels: Pixels<'_>) -> Vec<(u32, u32, Vec<u8>)> {
    let linear: Vec<f32> = (0..=255u8).map(to_linear).collect();
    let mut levels = vec![(pixels.width, pixels.height, pixels.rgba.to_vec())];
    loop {
        let (w, h, ref src) = *levels.last().expect("one level");
        if w == 1 && h == 1 {
            return levels;
        }
        let (nw, nh) = ((w / 2).max(1), (h / 2).max(1));
        let mut out = vec![0u8; nw as usize * nh as usize * 4];
        for y in 0..nh {
            for x in 0..nw {
                // The source texels this one covers (two or three a side).
                let xs = (x * 2)..if x + 1 == nw { w } else { x * 2 + 2 };
                let ys = (y * 2)..if y + 1 == nh { h } else { y * 2 + 2 };
                let (mut rgb, mut alpha, mut plain, mut n) = ([0f32; 3], 0f32, [0f32; 3], 0f32);
                for sy in ys {
                    for sx in xs.clone() {
                        let at = (sy as usize * w as usize + sx as usize) * 4;
                        let a = src[at + 3] as f32 / 255.0;
                        for c in 0..3 {
                            let l = linear[src[at + c] as usize];
                            rgb[c] += l * a;
                            plain[c] += l;
                        }
                        alpha += a;
                        n += 1.0;
                    }
                }
                let at = (y as usize * nw as usize + x as usize) * 4;
                for c in 0..3 {
                    // (Fully transparent texels: their plain mean, so the colour stays defined.)
                    let l = if alpha > 0.0 { rgb[c] / alpha } else { plain[c] / n };
                    out[at + c] = to_srgb(l);
                }
                out[at + 3] = (alpha / n * 255.0).round() as u8;
            }
        }
        levels.push((nw, nh, out));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mip_chain_halves_to_one_texel_and_keeps_the_mean() {
        let (w, h) = (5u32, 3u32);
        let rgba: Vec<u8> = (0..w * h).flat_map(|i| [(i * 10) as u8, 200, 0, 255]).collect();
        let levels = mip_chain(Pixels { width: w, height: h, rgba: &rgba });
        let sizes: Vec<(u32, u32)> = levels.iter().map(|l| (l.0, l.1)).collect();
        assert_eq!(sizes, vec![(5, 3), (2, 1), (1, 1)]);
        for (w, h, bytes) in &levels {
            assert_eq!(bytes.len(), (*w * *h * 4) as usize);
            assert!(bytes.chunks(4).all(|p| p[1] == 200 && p[3] == 255), "constant channels stay");
        }
        // The last level is the mean of all in linear light: above the sRGB bytes' plain mean.
        let mean_linear = (0..15).map(|i| to_linear((i * 10) as u8)).sum::<f32>() / 15.0;
        assert!((levels[2].2[0] as i32 - to_srgb(mean_linear) as i32).abs() <= 2, "{}", levels[2].2[0]);
    }

    #[test]
    fn transparent_texels_do_not_darken_the_colour_of_smaller_levels() {
        // White opaque beside black transparent: the half level is white at half alpha.
        let rgba = [255, 255, 255, 255, 0, 0, 0, 0];
        let levels = mip_chain(Pixels { width: 2, height: 1, rgba: &rgba });
        assert_eq!(levels[1].2, vec![255, 255, 255, 128]);
        assert_eq!((to_srgb(to_linear(200)), to_srgb(to_linear(3))), (200, 3));
    }

    #[test]
    fn quads_that_cannot_be_drawn_are_found() {
        let rgba = [255u8; 16];
        let ok = ReferenceQuad {
            key: 1,
            pixels: Pixels { width: 2, height: 2, rgba: &rgba },
            corners: [Vec3::ZERO, Vec3::X, Vec3::ONE, Vec3::Y],
            opacity: 0.5,
        };
        assert!(ok.drawable());
        assert!(!ReferenceQuad { opacity: 0.0, ..ok }.drawable());
        assert!(!ReferenceQuad { opacity: f32::NAN, ..ok }.drawable());
        assert!(!ReferenceQuad { corners: [Vec3::NAN, Vec3::X, Vec3::ONE, Vec3::Y], ..ok }.drawable());
        assert!(!ReferenceQuad { pixels: Pixels { width: 3, height: 2, rgba: &rgba }, ..ok }.drawable());
    }
}
