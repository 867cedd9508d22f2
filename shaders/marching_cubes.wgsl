// Marching cubes on voxel blocks, many chunks a dispatch, for strata-gpu-mesh.
//
// The same mesh as the CPU's `strata_mesh::mesh_block`, bit for bit in its positions and
// triangles: a vertex per stored edge crossing (the block's x crossings, then y, then z, placed
// exactly where the crossing is), and per mixed cell the triangles of its case from the same
// table (`strata_mesh::case_triangles`), cells in the CPU's order (x fastest, then y, then z), so
// that a prefix sum over the cells puts every triangle where the CPU puts it.
//
// Passes, each a dispatch:
//   count         one workgroup a chunk: each of 256 threads counts the triangles of a run of
//                 consecutive cells; a workgroup scan gives each thread's first triangle within
//                 the chunk and the chunk's total.
//   scan_chunks   one workgroup: the chunks' first triangles, the last entry the batch's total.
//   emit          one workgroup a chunk: each thread writes its cells' triangles.
//   place         one thread a crossing: its vertex's position, normal and material (the
//                 material of the edge's solid end, as the CPU's `edge_material`).
//   place_extra   one thread a seam point (a finer neighbour's vertex on a shared face): its
//                 vertex, placed on the CPU, with the material of the seam's first crossing.
//   split         one workgroup a block with seams: its triangles split where a seam passes,
//                 as the CPU's `split_seams` splits them (a fan from the opposite corner for one
//                 split edge, from a new centroid vertex for more), written after the batch's
//                 other triangles.
// And for drawing (`GpuMarcher::mesh_for_drawing`), after those:
//   world         one thread a vertex: the renderer's vertex (world position, normal, tint,
//                 material), placed by its block's placement.
//   draw_args     one thread a chunk: its indirect draw arguments (triangles, then edges).
//   edge_lines    one thread a triangle: its three edges as line-list indices (the wireframe).

struct Chunk {
    // Cells a side, nodes a side (n + 1), u32 words a row of node bits.
    n: u32,
    m: u32,
    words: u32,
    // Where this chunk's node bits start, and its crossing lookup (0xffffffff: none, the
    // crossing's index is its rank: see `crossing_index`).
    node_base: u32,
    lookup_base: u32,
    // The chunk's first vertex in the batch, and where its y and z crossings start after it.
    vertex_base: u32,
    y_base: u32,
    z_base: u32,
    // Grid units per cell (the block's level spacing) and the block's node 0 in its chunk.
    spacing: f32,
    off_x: u32,
    off_y: u32,
    off_z: u32,
    // Where the node materials start in `data` (four a word, node x + m (y + m z)), or
    // 0xffffffff when every node is material 0.
    material_base: u32,
    // Where the per-line crossing counts start (per axis and line along it: the crossings on the
    // lines before, then `words` words of the crossed edges along it).
    rows_base: u32,
    // The chunk's first crossing in `crossings` (its vertices start at `vertex_base`: the
    // crossings', then its seam points', then its centroids').
    crossing_base: u32,
    // Where its seam header starts in `data` (0xffffffff: no seams), its ordinal among the
    // blocks with seams, its first split triangle, and its first centroid vertex.
    seam_base: u32,
    seam_slot: u32,
    seam_out: u32,
    centroid_first: u32,
    // Dual contouring: where the chunk's crossings' (t, packed normal) pairs start in `data`.
    pair_base: u32,
};

struct Params {
    chunk_count: u32,
    crossing_count: u32,
    // Threads a row of the place and world dispatches (their x workgroups × 64).
    place_row: u32,
    // Threads a row of the edge_lines dispatch.
    edge_row: u32,
    // Vertex slots of the batch (crossings, seam points, centroid room).
    vertex_total: u32,
    // Triangle slots of the index buffer (the edge_lines dispatch's threads).
    triangle_slots: u32,
    // The seam points' records in `data` (8 words each: vertex, position, normal, the vertex
    // whose material it takes) and how many.
    extra_base: u32,
    extra_count: u32,
    // Where the list of seam headers (one word a block with seams: its header) starts in `data`.
    seam_list_base: u32,
    // Dual contouring's quads: 1 where the batch's volume mixes levels (its chunks' neighbour
    // tables then hold all 27 offsets, see `dual_contouring.wgsl`), 0 for one level.
    mixed: u32,
    unused_f: u32,
    unused_g: u32,
};

// Where a chunk's mesh is drawn: world = model · (origin + position), the sum in f32 (exact
// operands, so two chunks put a shared vertex on one world position bit for bit); normals by
// the inverse transpose; `tint` multiplies the materials' colours.
struct Placement {
    m0: vec4<f32>,
    m1: vec4<f32>,
    m2: vec4<f32>,
    m3: vec4<f32>,
    n0: vec4<f32>,
    n1: vec4<f32>,
    n2: vec4<f32>,
    origin: vec4<f32>,
    tint: vec4<f32>,
};

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> chunks: array<Chunk>;
// Read-only words (at most four storage buffers a stage, as downlevel adapters allow):
//   0..4096   the case table: per case 16 words, the triangle count, then three edges a
//             triangle, each axis | dx << 2 | dy << 3 | dz << 4;
//   node bits per chunk at `node_base`: row (y + m z) is `words` words, bit x node (x, y, z);
//   the crossing lookup per chunk at `lookup_base`, for a block whose crossings are not in
//             rank order: per axis m³ entries, the index among the chunk's crossings of that
//             axis of the edge whose lower node is (x, y, z), or 0xffffffff;
//   otherwise, at `rows_base`, per axis and line along it the crossings on the lines before and
//             the crossed edges' bits along it; an edge's index is those before its line plus
//             the crossed edges before it on the line (`crossing_index`).
@group(0) @binding(2) var<storage, read> data: array<u32>;
// Per crossing: lower node x | y << 8 | z << 16 | axis << 24, t's bits, the packed normal, the
// chunk.
@group(0) @binding(3) var<storage, read> crossings: array<vec4<u32>>;
// Scratch: each chunk's threads' first triangles (256 a chunk), then the chunks' triangle
// counts, then their first triangles and the batch's total.
@group(0) @binding(4) var<storage, read_write> scratch: array<u32>;
@group(0) @binding(5) var<storage, read_write> indices: array<u32>;
// Per vertex: position (3), normal (3) as their bits, material id. (Words, not floats: an
// integer kept in a float's bits is a denormal a GPU may flush.)
@group(0) @binding(6) var<storage, read_write> vertices: array<u32>;

fn vertex_float(i: u32) -> f32 {
    return bitcast<f32>(vertices[i]);
}

fn vertex_vec3(i: u32) -> vec3<f32> {
    return vec3<f32>(bitcast<f32>(vertices[i]), bitcast<f32>(vertices[i + 1u]), bitcast<f32>(vertices[i + 2u]));
}

fn set_vertex_vec3(i: u32, v: vec3<f32>) {
    vertices[i] = bitcast<u32>(v.x);
    vertices[i + 1u] = bitcast<u32>(v.y);
    vertices[i + 2u] = bitcast<u32>(v.z);
}

// For drawing: per chunk its placement; the renderer's vertices (12 words: position, normal,
// RGBA, material ids (a byte each), their weights); per chunk ten words of indirect draw
// arguments (indexed triangles, then indexed edges); two line indices an edge.
@group(0) @binding(7) var<storage, read> placements: array<Placement>;
@group(0) @binding(8) var<storage, read_write> drawn: array<u32>;
@group(0) @binding(9) var<storage, read_write> args: array<u32>;
@group(0) @binding(10) var<storage, read_write> edge_indices: array<u32>;

const THREADS: u32 = 256u;

// Where the scratch's parts start: per thread, per chunk, then per block with seams its split
// triangles and centroids.
fn seam_counts_at(j: u32) -> u32 {
    return params.chunk_count * (THREADS + 2u) + 1u + j * 2u;
}

fn chunk_triangles_at(k: u32) -> u32 {
    return params.chunk_count * THREADS + k;
}

fn chunk_first_at(k: u32) -> u32 {
    return params.chunk_count * (THREADS + 1u) + k;
}

var<workgroup> sums: array<u32, 256>;

// Whether node (x, y, z) of chunk `c` is inside.
fn inside(c: Chunk, x: u32, y: u32, z: u32) -> u32 {
    let word = data[c.node_base + (y + c.m * z) * c.words + x / 32u];
    return (word >> (x % 32u)) & 1u;
}

// Cell `i` (x fastest) of chunk `c`: its corner pattern, bit k for corner
// (k & 1, (k >> 1) & 1, (k >> 2) & 1).
fn case_of(c: Chunk, cell: vec3<u32>) -> u32 {
    var case_bits = 0u;
    for (var k = 0u; k < 8u; k++) {
        let corner = cell + vec3<u32>(k & 1u, (k >> 1u) & 1u, (k >> 2u) & 1u);
        case_bits |= inside(c, corner.x, corner.y, corner.z) << k;
    }
    return case_bits;
}

fn cell_at(c: Chunk, i: u32) -> vec3<u32> {
    return vec3<u32>(i % c.n, (i / c.n) % c.n, i / (c.n * c.n));
}

// The index among the chunk's crossings of `axis` of the edge from `node`: from the lookup, or
// its rank: the crossings on the lines along the axis before its line (line u + m v, u and v its
// coordinates across the axis as `Axis::across` orders them), then the crossed edges before it
// on its line.
fn crossing_index(c: Chunk, axis: u32, node: vec3<u32>, m3: u32) -> u32 {
    if (c.lookup_base != 0xffffffffu) {
        return data[c.lookup_base + axis * m3 + node.x + c.m * (node.y + c.m * node.z)];
    }
    var e = node.x;
    var line = node.y + c.m * node.z;
    if (axis == 1u) {
        e = node.y;
        line = node.z + c.m * node.x;
    } else if (axis == 2u) {
        e = node.z;
        line = node.x + c.m * node.y;
    }
    let stride = 1u + c.words;
    let at = c.rows_base + axis * c.m * c.m * stride + line * stride;
    var index = data[at];
    let last = e / 32u;
    for (var w = 0u; w < last; w++) {
        index += countOneBits(data[at + 1u + w]);
    }
    index += countOneBits(data[at + 1u + last] & ((1u << (e % 32u)) - 1u));
    return index;
}

// The cells thread `t` of a chunk's workgroup takes: a run of consecutive cells.
fn cell_run(c: Chunk, t: u32) -> vec2<u32> {
    let cells = c.n * c.n * c.n;
    let per = (cells + THREADS - 1u) / THREADS;
    return vec2<u32>(min(cells, t * per), min(cells, (t + 1u) * per));
}

// The exclusive prefix sum of `value` over the workgroup's threads (all of them must call it);
// afterwards `sums[THREADS - 1]` holds the total until the next call.
fn scan(t: u32, value: u32) -> u32 {
    sums[t] = value;
    workgroupBarrier();
    for (var d = 1u; d < THREADS; d = d * 2u) {
        var add = 0u;
        if (t >= d) {
            add = sums[t - d];
        }
        workgroupBarrier();
        sums[t] = sums[t] + add;
        workgroupBarrier();
    }
    return sums[t] - value;
}

@compute @workgroup_size(256)
fn count(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let k = wg.x;
    let c = chunks[k];
    let run = cell_run(c, t);
    var total = 0u;
    for (var i = run.x; i < run.y; i++) {
        total += data[case_of(c, cell_at(c, i)) * 16u];
    }
    let first = scan(t, total);
    scratch[k * THREADS + t] = first;
    if (t == THREADS - 1u) {
        scratch[chunk_triangles_at(k)] = first + total;
    }
}

@compute @workgroup_size(256)
fn scan_chunks(@builtin(local_invocation_index) t: u32) {
    let count = params.chunk_count;
    var carry = 0u;
    for (var start = 0u; start < count; start += THREADS) {
        let i = start + t;
        var value = 0u;
        if (i < count) {
            value = scratch[chunk_triangles_at(i)];
        }
        let first = scan(t, value);
        if (i < count) {
            scratch[chunk_first_at(i)] = carry + first;
        }
        carry += sums[THREADS - 1u];
        workgroupBarrier();
    }
    if (t == 0u) {
        scratch[chunk_first_at(count)] = carry;
    }
}

@compute @workgroup_size(256)
fn emit(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let k = wg.x;
    let c = chunks[k];
    let run = cell_run(c, t);
    let m3 = c.m * c.m * c.m;
    var at = (scratch[chunk_first_at(k)] + scratch[k * THREADS + t]) * 3u;
    for (var i = run.x; i < run.y; i++) {
        let cell = cell_at(c, i);
        let case_index = case_of(c, cell) * 16u;
        let triangles = data[case_index];
        for (var j = 0u; j < triangles * 3u; j++) {
            let code = data[case_index + 1u + j];
            let axis = code & 3u;
            let node = cell + vec3<u32>((code >> 2u) & 1u, (code >> 3u) & 1u, (code >> 4u) & 1u);
            let index = crossing_index(c, axis, node, m3);
            var base = c.vertex_base;
            if (axis == 1u) {
                base += c.y_base;
            } else if (axis == 2u) {
                base += c.z_base;
            }
            indices[at] = base + index;
            at += 1u;
        }
    }
}

// The unit normal of an octahedral-packed one (`strata_volume::normal::unpack_normal`).
fn unpack_normal(p: u32) -> vec3<f32> {
    let x = f32(p & 0xffu) / 255.0 * 2.0 - 1.0;
    let y = f32((p >> 8u) & 0xffu) / 255.0 * 2.0 - 1.0;
    let z = 1.0 - abs(x) - abs(y);
    var n = vec3<f32>(x, y, z);
    if (z < 0.0) {
        let sx = select(-1.0, 1.0, x >= 0.0);
        let sy = select(-1.0, 1.0, y >= 0.0);
        n = vec3<f32>((1.0 - abs(y)) * sx, (1.0 - abs(x)) * sy, z);
    }
    return normalize(n);
}

@compute @workgroup_size(64)
fn place(@builtin(global_invocation_id) g: vec3<u32>) {
    let i = g.x + g.y * params.place_row;
    if (i >= params.crossing_count) {
        return;
    }
    let q = crossings[i];
    let c = chunks[q.w];
    let axis = q.x >> 24u;
    var p = vec3<f32>(
        f32((q.x & 0xffu) + c.off_x),
        f32(((q.x >> 8u) & 0xffu) + c.off_y),
        f32(((q.x >> 16u) & 0xffu) + c.off_z),
    );
    p[axis] = p[axis] + bitcast<f32>(q.y);
    p = p * c.spacing;
    let n = unpack_normal(q.z);
    // The edge's solid end: its lower node if inside, else its upper one.
    var end = vec3<u32>(q.x & 0xffu, (q.x >> 8u) & 0xffu, (q.x >> 16u) & 0xffu);
    if (inside(c, end.x, end.y, end.z) == 0u) {
        end[axis] = end[axis] + 1u;
    }
    var material = 0u;
    if (c.material_base != 0xffffffffu) {
        let node = end.x + c.m * (end.y + c.m * end.z);
        material = (data[c.material_base + node / 4u] >> (8u * (node % 4u))) & 0xffu;
    }
    let at = (c.vertex_base + i - c.crossing_base) * 7u;
    set_vertex_vec3(at, p);
    set_vertex_vec3(at + 3u, n);
    vertices[at + 6u] = material;
}

@compute @workgroup_size(64)
fn world(@builtin(global_invocation_id) g: vec3<u32>) {
    let i = g.x + g.y * params.place_row;
    if (i >= params.vertex_total) {
        return;
    }
    // The block holding vertex slot i: the last whose first vertex is at most i.
    var lo = 0u;
    var hi = params.chunk_count;
    while (hi - lo > 1u) {
        let mid = (lo + hi) / 2u;
        if (chunks[mid].vertex_base <= i) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let at = i * 7u;
    // One material, whole, in every slot as the CPU's `VertexMaterial::single` (material 0
    // where the block has none).
    let material = (vertices[at + 6u] & 0xffu) * 0x01010101u;
    write_drawn(i * 12u, placements[lo], vertex_vec3(at), vertex_vec3(at + 3u), material, 255u);
}

// Writes the renderer's vertex at word `out` of `drawn`: `position` and `normal` (in the
// chunk's grid) placed by `p`, its tint, and the material ids and weights given.
fn write_drawn(out: u32, p: Placement, position: vec3<f32>, normal: vec3<f32>, ids: u32, weights: u32) {
    let grid = p.origin.xyz + position;
    let w = p.m0 * grid.x + p.m1 * grid.y + p.m2 * grid.z + p.m3;
    var n = p.n0.xyz * normal.x + p.n1.xyz * normal.y + p.n2.xyz * normal.z;
    let length_squared = dot(n, n);
    if (length_squared > 0.0) {
        n = n * inverseSqrt(length_squared);
    } else {
        n = vec3<f32>(0.0, 1.0, 0.0);
    }
    drawn[out] = bitcast<u32>(w.x);
    drawn[out + 1u] = bitcast<u32>(w.y);
    drawn[out + 2u] = bitcast<u32>(w.z);
    drawn[out + 3u] = bitcast<u32>(n.x);
    drawn[out + 4u] = bitcast<u32>(n.y);
    drawn[out + 5u] = bitcast<u32>(n.z);
    drawn[out + 6u] = bitcast<u32>(p.tint.x);
    drawn[out + 7u] = bitcast<u32>(p.tint.y);
    drawn[out + 8u] = bitcast<u32>(p.tint.z);
    drawn[out + 9u] = bitcast<u32>(p.tint.w);
    drawn[out + 10u] = ids;
    drawn[out + 11u] = weights;
}

@compute @workgroup_size(64)
fn draw_args(@builtin(global_invocation_id) g: vec3<u32>) {
    let k = g.x;
    if (k >= params.chunk_count) {
        return;
    }
    var first = scratch[chunk_first_at(k)];
    var triangles = scratch[chunk_first_at(k + 1u)] - first;
    let c = chunks[k];
    if (c.seam_slot != 0xffffffffu) {
        first = c.seam_out;
        triangles = scratch[seam_counts_at(c.seam_slot)];
    }
    write_args(k, first, triangles);
}

// Chunk `k`'s indirect indexed-draw arguments: its `triangles` from triangle slot `first`, then
// their lines (six indices a triangle, from the same slot in the lines).
fn write_args(k: u32, first: u32, triangles: u32) {
    let a = k * 10u;
    args[a] = triangles * 3u;
    args[a + 1u] = 1u;
    args[a + 2u] = first * 3u;
    args[a + 3u] = 0u;
    args[a + 4u] = 0u;
    args[a + 5u] = triangles * 6u;
    args[a + 6u] = 1u;
    args[a + 7u] = first * 6u;
    args[a + 8u] = 0u;
    args[a + 9u] = 0u;
}

@compute @workgroup_size(64)
fn edge_lines(@builtin(global_invocation_id) g: vec3<u32>) {
    // Every triangle slot (unused ones give lines no draw reaches).
    let t = g.x + g.y * params.edge_row;
    if (t >= params.triangle_slots) {
        return;
    }
    let a = indices[t * 3u];
    let b = indices[t * 3u + 1u];
    let c = indices[t * 3u + 2u];
    let at = t * 6u;
    edge_indices[at] = a;
    edge_indices[at + 1u] = b;
    edge_indices[at + 2u] = b;
    edge_indices[at + 3u] = c;
    edge_indices[at + 4u] = c;
    edge_indices[at + 5u] = a;
}

@compute @workgroup_size(64)
fn place_extra(@builtin(global_invocation_id) g: vec3<u32>) {
    let i = g.x + g.y * params.place_row;
    if (i >= params.extra_count) {
        return;
    }
    let r = params.extra_base + i * 8u;
    let at = data[r] * 7u;
    for (var w = 0u; w < 6u; w++) {
        vertices[at + w] = data[r + 1u + w];
    }
    vertices[at + 6u] = vertices[data[r + 7u] * 7u + 6u];
}

// A seam header in `data`: entry count S, block, first split triangle, first centroid vertex,
// ordinal; then S entries (4 words: from vertex a, to vertex b, first point vertex, point
// count) sorted by (a, b).
struct Chain {
    first: u32,
    count: u32,
    reversed: bool,
    found: bool,
};

fn find_entry(h: u32, a: u32, b: u32) -> u32 {
    var lo = 0u;
    var hi = data[h];
    while (lo < hi) {
        let mid = (lo + hi) / 2u;
        let e = h + 5u + mid * 4u;
        let ea = data[e];
        let eb = data[e + 1u];
        if (ea < a || (ea == a && eb < b)) {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    if (lo < data[h]) {
        let e = h + 5u + lo * 4u;
        if (data[e] == a && data[e + 1u] == b) {
            return e;
        }
    }
    return 0xffffffffu;
}

// The points splitting edge (a, b) of a triangle, in order from a (as the CPU's `chain`).
fn chain(h: u32, a: u32, b: u32) -> Chain {
    var e = find_entry(h, a, b);
    if (e != 0xffffffffu) {
        return Chain(data[e + 2u], data[e + 3u], false, true);
    }
    e = find_entry(h, b, a);
    if (e != 0xffffffffu) {
        return Chain(data[e + 2u], data[e + 3u], true, true);
    }
    return Chain(0u, 0u, false, false);
}

// Point j of a chain.
fn chain_point(c: Chain, j: u32) -> u32 {
    if (c.reversed) {
        return c.first + c.count - 1u - j;
    }
    return c.first + j;
}

// Vertex r of a triangle's ring (its corners, each followed by the points splitting the edge to
// the next one).
fn ring_at(t: array<u32, 3>, ch: array<Chain, 3>, r: u32) -> u32 {
    var left = r;
    for (var k = 0u; k < 3u; k++) {
        if (left == 0u) {
            return t[k];
        }
        left -= 1u;
        if (left < ch[k].count) {
            return chain_point(ch[k], left);
        }
        left -= ch[k].count;
    }
    return t[0];
}

@compute @workgroup_size(256)
fn split(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let h = data[params.seam_list_base + wg.x];
    let k = data[h + 1u];
    let out_base = data[h + 2u];
    let centroid_first = data[h + 3u];
    let slot = data[h + 4u];
    let in_first = scratch[chunk_first_at(k)];
    let total = scratch[chunk_first_at(k + 1u)] - in_first;
    let per = (total + THREADS - 1u) / THREADS;
    let run_from = min(total, t * per);
    let run_to = min(total, (t + 1u) * per);
    // Count what this thread's triangles become.
    var out_count = 0u;
    var centroids = 0u;
    for (var i = run_from; i < run_to; i++) {
        let at = (in_first + i) * 3u;
        let tri = array<u32, 3>(indices[at], indices[at + 1u], indices[at + 2u]);
        let ch = array<Chain, 3>(chain(h, tri[0], tri[1]), chain(h, tri[1], tri[2]), chain(h, tri[2], tri[0]));
        let splits = u32(ch[0].found) + u32(ch[1].found) + u32(ch[2].found);
        if (splits == 0u) {
            out_count += 1u;
        } else if (splits == 1u) {
            out_count += ch[0].count + ch[1].count + ch[2].count + 1u;
        } else {
            out_count += 3u + ch[0].count + ch[1].count + ch[2].count;
            centroids += 1u;
        }
    }
    let first_out = scan(t, out_count);
    let all_out = sums[THREADS - 1u];
    workgroupBarrier();
    let first_centroid = scan(t, centroids);
    let all_centroids = sums[THREADS - 1u];
    if (t == 0u) {
        scratch[seam_counts_at(slot)] = all_out;
        scratch[seam_counts_at(slot) + 1u] = all_centroids;
    }
    // Write them.
    var w = (out_base + first_out) * 3u;
    var m = centroid_first + first_centroid;
    for (var i = run_from; i < run_to; i++) {
        let at = (in_first + i) * 3u;
        let tri = array<u32, 3>(indices[at], indices[at + 1u], indices[at + 2u]);
        let ch = array<Chain, 3>(chain(h, tri[0], tri[1]), chain(h, tri[1], tri[2]), chain(h, tri[2], tri[0]));
        let splits = u32(ch[0].found) + u32(ch[1].found) + u32(ch[2].found);
        if (splits == 0u) {
            indices[w] = tri[0];
            indices[w + 1u] = tri[1];
            indices[w + 2u] = tri[2];
            w += 3u;
        } else if (splits == 1u) {
            var s = 0u;
            if (ch[1].found) {
                s = 1u;
            } else if (ch[2].found) {
                s = 2u;
            }
            let a = tri[s];
            let b = tri[(s + 1u) % 3u];
            let c = tri[(s + 2u) % 3u];
            let n = ch[s].count;
            // The path a, the chain, b: a fan from c over its windows.
            for (var q = 0u; q <= n; q++) {
                var p0 = a;
                if (q > 0u) {
                    p0 = chain_point(ch[s], q - 1u);
                }
                var p1 = b;
                if (q < n) {
                    p1 = chain_point(ch[s], q);
                }
                indices[w] = c;
                indices[w + 1u] = p0;
                indices[w + 2u] = p1;
                w += 3u;
            }
        } else {
            // The centroid: positions summed in order and divided by three, normals summed and
            // normalised, the material of the first corner (as the CPU does).
            var pos = vec3<f32>(0.0);
            var nor = vec3<f32>(0.0);
            for (var q = 0u; q < 3u; q++) {
                let v = tri[q] * 7u;
                pos = pos + vertex_vec3(v);
                nor = nor + vertex_vec3(v + 3u);
            }
            pos = pos / 3.0;
            nor = nor / max(sqrt(dot(nor, nor)), 1e-12);
            let mv = m * 7u;
            set_vertex_vec3(mv, pos);
            set_vertex_vec3(mv + 3u, nor);
            vertices[mv + 6u] = vertices[tri[0] * 7u + 6u];
            let ring = 3u + ch[0].count + ch[1].count + ch[2].count;
            for (var r = 0u; r < ring; r++) {
                indices[w] = m;
                indices[w + 1u] = ring_at(tri, ch, r);
                indices[w + 2u] = ring_at(tri, ch, (r + 1u) % ring);
                w += 3u;
            }
            m += 1u;
        }
    }
}
