// Chunk meshes, wireframe, grid and brush preview for strata-render.
//
// One uniform block for the frame and one for the material palette. Vertices are in world space
// (the renderer applies each layer's transform when it uploads a chunk): position, normal,
// linear RGBA colour (a tint for meshes, the colour itself for lines and previews), and up to
// four material ids with weights (unorm bytes summing to 1; all zero for lines and previews).
//
// Materials are textured triplanar: each of the three axis projections of a procedural detail
// texture (a layer of `detail`) is weighted by normalize(|n|^k), the weights summing to 1, and
// the vertex's materials are blended by their weights: the vertex shader mixes their colours,
// texture scales, roughness and texture layers, and the fragment interpolates the mixes, so a
// triangle between vertices of different materials blends smoothly from one to the other.

struct Frame {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,
    // Direction towards the key light (unit), w unused.
    light_dir: vec4<f32>,
    // Colour of wireframe lines.
    line_color: vec4<f32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;

// One palette entry: linear colour (a unused), then (texture layer, world units per repeat,
// roughness, unused).
struct PaletteEntry {
    color: vec4<f32>,
    params: vec4<f32>,
};

struct Palette {
    entries: array<PaletteEntry, 256>,
};

@group(0) @binding(1) var<uniform> palette: Palette;
@group(0) @binding(2) var detail: texture_2d_array<f32>;
@group(0) @binding(3) var detail_sampler: sampler;

// Sharpness of the triplanar blend.
const TRIPLANAR_K: f32 = 4.0;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
    @location(3) ids: vec4<u32>,
    @location(4) weights: vec4<f32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
    // Weights of texture layers 0..3 and 4..5 (all zero: not a material surface).
    @location(3) layers_a: vec4<f32>,
    @location(4) layers_b: vec2<f32>,
    // (world units per repeat, roughness)
    @location(5) surface: vec2<f32>,
};

// World to clip space, passing the attributes on and mixing the vertex's materials.
fn transform(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.color = v.color;
    out.layers_a = vec4<f32>(0.0);
    out.layers_b = vec2<f32>(0.0);
    out.surface = vec2<f32>(16.0, 0.7);
    let total = v.weights.x + v.weights.y + v.weights.z + v.weights.w;
    if (total > 0.0) {
        var albedo = vec3<f32>(0.0);
        var surface = vec2<f32>(0.0);
        var la = vec4<f32>(0.0);
        var lb = vec2<f32>(0.0);
        for (var i = 0u; i < 4u; i = i + 1u) {
            let w = v.weights[i] / total;
            let e = palette.entries[min(v.ids[i], 255u)];
            albedo = albedo + e.color.rgb * w;
            surface = surface + e.params.yz * w;
            let layer = u32(e.params.x);
            if (layer < 4u) {
                la[layer] = la[layer] + w;
            } else {
                lb[min(layer - 4u, 1u)] = lb[min(layer - 4u, 1u)] + w;
            }
        }
        out.color = vec4<f32>(albedo * v.color.rgb, v.color.a);
        out.layers_a = la;
        out.layers_b = lb;
        out.surface = surface;
    }
    return out;
}

// The triplanar sample of texture layer `layer` at `p` (texture units) with blend weights `w`.
fn triplanar(layer: i32, p: vec3<f32>, w: vec3<f32>) -> f32 {
    let x = textureSample(detail, detail_sampler, p.yz, layer).r;
    let y = textureSample(detail, detail_sampler, p.zx, layer).r;
    let z = textureSample(detail, detail_sampler, p.xy, layer).r;
    return x * w.x + y * w.y + z * w.z;
}

// The blended detail of a material surface in [0, 1] (0.5: no change to the colour).
fn surface_detail(in: VertexOut, n: vec3<f32>) -> f32 {
    let a = pow(abs(n), vec3<f32>(TRIPLANAR_K));
    let w = a / max(a.x + a.y + a.z, 1e-6);
    let p = in.world / max(in.surface.x, 1e-3);
    var d = 0.0;
    for (var i = 0; i < 4; i = i + 1) {
        d = d + triplanar(i, p, w) * in.layers_a[i];
    }
    d = d + triplanar(4, p, w) * in.layers_b.x + triplanar(5, p, w) * in.layers_b.y;
    return d;
}

@vertex
fn vs_mesh(v: VertexIn) -> VertexOut {
    return transform(v);
}

// A key light (Lambert plus a soft Blinn-Phong highlight) over a hemispheric ambient: sky
// colour from above, ground bounce from below, so form reads even on the unlit side.
@fragment
fn fs_mesh(in: VertexOut) -> @location(0) vec4<f32> {
    let n = normalize(in.normal);
    let l = frame.light_dir.xyz;
    let v = normalize(frame.eye.xyz - in.world);
    let h = normalize(l + v);
    let sky = vec3<f32>(0.62, 0.70, 0.85);
    let ground = vec3<f32>(0.30, 0.26, 0.22);
    let ambient = mix(ground, sky, 0.5 + 0.5 * n.y) * 0.38;
    let diffuse = max(dot(n, l), 0.0) * 1.05;
    // (Sampled outside any branch: texture sampling needs uniform control flow.)
    let d = surface_detail(in, n);
    let textured = in.layers_a.x + in.layers_a.y + in.layers_a.z + in.layers_a.w + in.layers_b.x + in.layers_b.y;
    let factor = mix(1.0, 0.55 + 0.9 * d, clamp(textured, 0.0, 1.0));
    let rough = clamp(in.surface.y, 0.0, 1.0);
    let spec = pow(max(dot(n, h), 0.0), mix(80.0, 8.0, rough)) * mix(0.25, 0.04, rough);
    let rgb = in.color.rgb * factor * (ambient + vec3<f32>(diffuse)) + vec3<f32>(spec);
    return vec4<f32>(rgb, in.color.a);
}

// Lines (wireframe over the mesh, and the ground grid): drawn slightly towards the camera so
// they win the depth test against the surface they lie on.
@vertex
fn vs_line(v: VertexIn) -> VertexOut {
    var out = transform(v);
    out.clip.z = out.clip.z - 0.0004 * out.clip.w;
    return out;
}

// Wireframe lines take the frame's line colour.
@fragment
fn fs_wire(in: VertexOut) -> @location(0) vec4<f32> {
    return frame.line_color;
}

// Grid lines carry their own colour.
@fragment
fn fs_grid(in: VertexOut) -> @location(0) vec4<f32> {
    return in.color;
}

// The translucent brush preview: lit like a mesh, alpha from the vertex colour.
@fragment
fn fs_preview(in: VertexOut) -> @location(0) vec4<f32> {
    let n = normalize(in.normal);
    let rim = 1.0 - abs(dot(n, normalize(frame.eye.xyz - in.world)));
    return vec4<f32>(in.color.rgb * (0.6 + 0.4 * rim), in.color.a * (0.5 + 0.5 * rim));
}
