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
    // Unit vector from the camera's target towards the eye; w: 1 for an orthographic
    // projection, 0 for a perspective one.
    view_axis: vec4<f32>,
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

// `v` scaled to unit length, or `fallback` where `v` is too short to have a direction: WGSL's
// normalize of a zero vector is undefined (NaN on many GPUs, which shades black). |v|² > 1e-24
// (|v| > 1e-12) keeps v·v and its inverse square root far from f32 denormals and overflow.
fn safe_normalize(v: vec3<f32>, fallback: vec3<f32>) -> vec3<f32> {
    let l2 = dot(v, v);
    return select(fallback, v * inverseSqrt(l2), l2 > 1e-24);
}

// The unit normal of the triangle being drawn, from the screen-space derivatives of the world
// position, turned towards the eye (`to_eye`, unit). Derivatives need uniform control flow: call
// this first in a fragment shader, outside any branch.
fn geometric_normal(world: vec3<f32>, to_eye: vec3<f32>) -> vec3<f32> {
    let g = safe_normalize(cross(dpdx(world), dpdy(world)), to_eye);
    return select(-g, g, dot(g, to_eye) >= 0.0);
}

// The normal to shade with: the interpolated vertex normal where the triangle's vertex normals
// agree, the triangle's own normal `g` (unit, on the visible side) where they do not.
//
// Why: at thin features (horn tips, tubes and sheets a cell or two thick, fillets) a
// marching-cubes triangle can join vertices from opposite sides of the feature, whose normals
// point nearly opposite ways. The interpolated normal then passes through zero inside the
// triangle: around that point its direction is arbitrary, often facing down or away from the
// light (a dark speck, as dark as the ground bounce alone), and at zero normalize gives NaN
// (black). On the thin-feature test model of `tests/headless.rs` (tori of minor radius 1 and
// 0.7 cells, capsules of 0.6 to 1.4, a tapered horn, three grabbed horns), 268 of 10,244
// triangles interpolate to |n| < 0.5 and 42 to |n| < 0.05; seen from above (lavapipe), they
// made 2-6 pixel specks at 30-40 % of the brightness of the same surface with those triangles
// flat-shaded: 57 pixels below 40 % in the test's 8 views, none with this function.
//
// Trust in the vertex normals falls from 1 to 0 as |n| falls from 0.7 to 0.4: unit normals θ
// apart interpolate to at least cos(θ/2), so normals up to ~90° apart are trusted fully (box
// and cylinder edges give 0.71) and those over ~130° apart not at all. It falls too as the
// normal turns from the face past 53° (dot 0.6) to 73° (dot 0.3): the specks left by the length
// test alone had normals 77-81° off their face. On smooth models (spheres, a box, a cylinder,
// grabbed horns) this changes only the bevel triangles along the cylinder's sharp rims. Where
// `s` is used at all, dot(s, g) >= 0.3, so the blend is never shorter than ~0.8.
fn shading_normal(interpolated: vec3<f32>, g: vec3<f32>) -> vec3<f32> {
    let len = length(interpolated);
    let s = safe_normalize(interpolated, g);
    let trust = smoothstep(0.4, 0.7, len) * smoothstep(0.3, 0.6, dot(s, g));
    return safe_normalize(mix(g, s, trust), g);
}

// A key light (Lambert plus a soft Blinn-Phong highlight) over a hemispheric ambient: sky
// colour from above, ground bounce from below, so form reads even on the unlit side.
@fragment
fn fs_mesh(in: VertexOut) -> @location(0) vec4<f32> {
    let v = safe_normalize(frame.eye.xyz - in.world, vec3<f32>(0.0, 1.0, 0.0));
    // (Back faces are culled: the triangle faces the eye, so `g` is its outward normal.)
    let n = shading_normal(in.normal, geometric_normal(in.world, v));
    let l = frame.light_dir.xyz;
    // (l + v vanishes only with the eye exactly opposite the light, where a surface facing the
    // eye is unlit: no half vector, no highlight.)
    let h = safe_normalize(l + v, vec3<f32>(0.0));
    let sky = vec3<f32>(0.62, 0.70, 0.85);
    let ground = vec3<f32>(0.30, 0.26, 0.22);
    let ambient = mix(ground, sky, 0.5 + 0.5 * n.y) * 0.38;
    let diffuse = max(dot(n, l), 0.0) * 1.05;
    // (Sampled outside any branch: texture sampling needs uniform control flow.)
    let d = surface_detail(in, n);
    let textured = in.layers_a.x + in.layers_a.y + in.layers_a.z + in.layers_a.w + in.layers_b.x + in.layers_b.y;
    let factor = mix(1.0, 0.55 + 0.9 * d, clamp(textured, 0.0, 1.0));
    let rough = clamp(in.surface.y, 0.0, 1.0);
    // (pow(0, e) is 0 for e > 0, the only case here: the exponent is 8 to 80.)
    let spec = pow(max(dot(n, h), 0.0), mix(80.0, 8.0, rough)) * mix(0.25, 0.04, rough);
    let rgb = in.color.rgb * factor * (ambient + vec3<f32>(diffuse)) + vec3<f32>(spec);
    return vec4<f32>(rgb, in.color.a);
}

// Lines (wireframe over the mesh, and the ground grid) are moved towards the eye by a fraction
// of their view depth, along the ray they are seen on (so they stay on the same pixels). WebGPU
// allows no pipeline depth bias for line topologies, hence the move here.
//
// It used to be a fixed clip-space offset (z − 0.0004·w): with the depth 0..1 perspective and
// z = f/(f − n)·(1 − n/d), that is a pull of about 0.0004·d²/n in world units, which grows with
// the square of the distance. For the default camera (distance 110, n = 1.1, f = 3200) it was
// 4.4 units at the target, 33 at d = 300 and 360 at d = 1000, so the grid and the axes showed
// through any box, model or hill lower than that above the ground.
//
// The smallest useful pull is set by the depth buffer: Depth32Float steps by 2⁻²⁴ near 1, which
// is 6e-8·d²/n in world units, i.e. 6e-8·d/n of the distance: 1.7e-4 at the far plane of the
// default camera (f/n = 2000 + 10⁵/distance = 2900). LINE_PULL = 1e-3 is six such steps there:
// 0.11 units at distance 110, 1 unit at 1000.
const LINE_PULL: f32 = 1e-3;
// Wireframe lines lie on the mesh and must still win over it: a line's pixel centre lies up to
// half a pixel off the edge, where the neighbouring triangle of a surface tilted by θ from the
// view is nearer by up to ½·pixel·tan θ. A pixel spans 2·tan(fov/2)/height of the distance:
// 0.0035 at 240 pixels and fov 0.8, 0.0008 at 1080. So wire lines also move by
// WIRE_PULL_SLOPE·tan θ (θ from the vertex normal, tan θ at most WIRE_MAX_TAN = 8, 83°): half a
// pixel at 240 pixels tall, over a pixel from 480, at most 1.7 % of the distance at grazing
// edges. The grid lies on nothing (normally), so it moves by LINE_PULL alone.
const WIRE_PULL_SLOPE: f32 = 2e-3;
const WIRE_MAX_TAN: f32 = 8.0;

// `v` transformed with its position moved `fraction` of the way towards the eye along its view
// ray (the ray to the eye in perspective, the view axis in an orthographic view).
fn pulled(v: VertexIn, fraction: f32) -> VertexOut {
    let to_eye = frame.eye.xyz - v.position;
    let axis = frame.view_axis.xyz;
    let ray = select(to_eye, axis * dot(to_eye, axis), frame.view_axis.w > 0.5);
    var moved = v;
    moved.position = v.position + ray * fraction;
    return transform(moved);
}

@vertex
fn vs_line(v: VertexIn) -> VertexOut {
    let to_eye = safe_normalize(frame.eye.xyz - v.position, frame.view_axis.xyz);
    let ray = select(to_eye, frame.view_axis.xyz, frame.view_axis.w > 0.5);
    let c = abs(dot(safe_normalize(v.normal, ray), ray));
    let tan_theta = min(sqrt(max(1.0 - c * c, 0.0)) / max(c, 1e-3), WIRE_MAX_TAN);
    return pulled(v, LINE_PULL + WIRE_PULL_SLOPE * tan_theta);
}

@vertex
fn vs_grid(v: VertexIn) -> VertexOut {
    return pulled(v, LINE_PULL);
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

// The translucent brush preview: lit like a mesh, alpha from the vertex colour. Drawn without
// culling, so the triangle's normal is turned to the side the vertex normal is on (the rim term
// only needs the normal up to sign).
@fragment
fn fs_preview(in: VertexOut) -> @location(0) vec4<f32> {
    let v = safe_normalize(frame.eye.xyz - in.world, vec3<f32>(0.0, 1.0, 0.0));
    let g = geometric_normal(in.world, v);
    let n = shading_normal(in.normal, select(-g, g, dot(g, in.normal) >= 0.0));
    let rim = 1.0 - abs(dot(n, v));
    return vec4<f32>(in.color.rgb * (0.6 + 0.4 * rim), in.color.a * (0.5 + 0.5 * rim));
}

// Reference images: a picture on a quad in world space (its own texture in group 1), blended by
// its opacity over what is behind it; depth-tested but not written, so the model in front of a
// picture hides it and a picture hides nothing. Texels are straight-alpha sRGB (the texture's
// format decodes them to linear).
struct ReferenceIn {
    @location(0) position: vec3<f32>,
    @location(1) uv: vec2<f32>,
    @location(2) opacity: f32,
};

struct ReferenceOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) opacity: f32,
};

@group(1) @binding(0) var picture: texture_2d<f32>;
@group(1) @binding(1) var picture_sampler: sampler;

@vertex
fn vs_reference(v: ReferenceIn) -> ReferenceOut {
    var out: ReferenceOut;
    out.clip = frame.view_proj * vec4<f32>(v.position, 1.0);
    out.uv = v.uv;
    out.opacity = v.opacity;
    return out;
}

@fragment
fn fs_reference(in: ReferenceOut) -> @location(0) vec4<f32> {
    let texel = textureSample(picture, picture_sampler, in.uv);
    return vec4<f32>(texel.rgb, texel.a * in.opacity);
}
