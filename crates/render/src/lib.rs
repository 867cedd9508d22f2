//! # strata-render
//!
//! A wgpu renderer for meshes, used on screen (inside the egui desktop app) and headless (an
//! offscreen texture read back to a PNG: [`screenshot`]). GPU buffers live per mesh, named by
//! an opaque [`MeshId`] the caller chooses, and are replaced only for the meshes a remesh
//! touched; the renderer knows nothing of volumes or chunks, only meshes and where they are
//! placed ([`Placement`]). Lighting is a key light over a hemispheric ambient; a ground grid
//! gives scale, a translucent brush preview shows where the tool will act, and a wireframe
//! overlay shows the triangles. Meshes are textured by material: each vertex blends up to four
//! entries of a palette ([`Renderer::set_palette`]: colour, procedural detail texture, scale,
//! roughness), projected triplanar (see [`textures`]). Reference pictures ([`ReferenceQuad`])
//! are drawn as translucent quads in the world. The WGSL source is `shaders/mesh.wgsl`,
//! embedded here.
#![warn(missing_docs)]

mod camera;
mod gpu;
mod references;
mod renderer;
pub mod textures;

pub use camera::{AxisView, Camera};
pub use gpu::{DrawMesh, Gpu, Image, RenderError, render_offscreen, screenshot};
pub use references::{KEPT_TEXTURES, Pixels, ReferenceQuad};
pub use renderer::{
    DEPTH_FORMAT, FrameSettings, IndirectMesh, MaterialBlend, MeshId, MeshRef, PALETTE_SIZE, PaletteEntry, Placement,
    Preview, Renderer, Vertex, placed_vertices,
};

/// The WGSL source of every pipeline.
pub const SHADER: &str = include_str!("../../../shaders/mesh.wgsl");

#[cfg(test)]
mod tests {
    #[test]
    fn the_shader_parses_and_validates() {
        let module = naga::front::wgsl::parse_str(super::SHADER).expect("WGSL parses");
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), naga::valid::Capabilities::default())
            .validate(&module)
            .expect("WGSL validates");
        for entry in [
            "vs_mesh",
            "fs_mesh",
            "vs_line",
            "vs_grid",
            "fs_wire",
            "fs_grid",
            "fs_preview",
            "vs_reference",
            "fs_reference",
        ] {
            assert!(module.entry_points.iter().any(|e| e.name == entry), "{entry}");
        }
    }
}
