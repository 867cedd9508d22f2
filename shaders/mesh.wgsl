// Chunk meshes, wireframe, grid and brush preview for strata-render.
//
// One uniform block for the frame. Vertices are in world space (the renderer applies each
// layer's transform when it uploads a chunk): position, normal, linear RGBA colour.

struct Frame {
    view_proj: mat4x4<f32>,
    eye: vec4<f32>,
    // Direction towards the key light (unit), w unused.
    light_dir: vec4<f32>,
    // Colour of wireframe lines.
    line_color: vec4<f32>,
};

@group(0) @binding(0) var<uniform> frame: Frame;

struct VertexIn {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
};

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) world: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) color: vec4<f32>,
};

// World to clip space, passing the attributes on.
fn transform(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = frame.view_proj * vec4<f32>(v.position, 1.0);
    out.world = v.position;
    out.normal = v.normal;
    out.color = v.color;
    return out;
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
    let spec = pow(max(dot(n, h), 0.0), 40.0) * 0.12;
    let rgb = in.color.rgb * (ambient + vec3<f32>(diffuse)) + vec3<f32>(spec);
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
