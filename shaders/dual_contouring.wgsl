// Dual contouring's vertices on voxel blocks, for strata-gpu-mesh: appended to
// `marching_cubes.wgsl` (its bindings, node bits, crossing ranks and scans), one module.
//
// The same vertices as the CPU's manifold dual contouring (`strata_mesh::dual_vertices`): per
// mixed cell one vertex per surface component (per marching-cubes loop of its case, from the
// CPU's own table, `strata_mesh::case_components`), placed by the QEF of that component's
// crossings with the CPU's stable solve (around the mass point; nearly parallel planes by the
// mean normal alone; otherwise a Jacobi eigen-decomposition of AᵀA with the same relative cut
// at 0.02) and clamped to the cell grown by half a cell; the normal is the crossings' normals
// summed; the material blends the cell's solid corners as `VertexMaterial::blend` does. The CPU
// solves in f64 and the GPU in f32: positions agree within 1e-4 cells.
//
// Passes:
//   dual_count    one workgroup a chunk: components of each thread's run of cells, scanned.
//   scan_chunks   (as for marching cubes) each chunk's first vertex.
//   dual_emit     one workgroup a chunk: each thread's cells' vertices, ten words each (cell,
//                 edges, position, normal, material ids, weights), and every cell's first vertex
//                 in the chunk's cell table (in the scratch, at `crossing_base`).
//
// Data: the component table after the case table (per case five words: the count, then up to
// four edge masks), and per chunk at `pair_base` two words a crossing (t's bits, the packed
// normal) in the block's order (x crossings, then y, then z).

const DUAL_TABLE: u32 = 4096u;
const EIGEN_CUTOFF: f32 = 0.02;
const CELL_MARGIN: f32 = 0.5;

@compute @workgroup_size(256)
fn dual_count(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let k = wg.x;
    let c = chunks[k];
    let run = cell_run(c, t);
    var total = 0u;
    for (var i = run.x; i < run.y; i++) {
        total += data[DUAL_TABLE + case_of(c, cell_at(c, i)) * 5u];
    }
    let first = scan(t, total);
    scratch[k * THREADS + t] = first;
    if (t == THREADS - 1u) {
        scratch[chunk_triangles_at(k)] = first + total;
    }
}

// Eigenvalues (diagonal) and eigenvectors (columns of `v`) of a symmetric 3×3 matrix by cyclic
// Jacobi rotations, as the CPU's `symmetric_eigen`.
struct Eigen {
    values: vec3<f32>,
    v: array<array<f32, 3>, 3>,
};

fn symmetric_eigen(m: array<array<f32, 3>, 3>) -> Eigen {
    var a = m;
    var v = array<array<f32, 3>, 3>(
        array<f32, 3>(1.0, 0.0, 0.0),
        array<f32, 3>(0.0, 1.0, 0.0),
        array<f32, 3>(0.0, 0.0, 1.0),
    );
    for (var sweep = 0u; sweep < 32u; sweep++) {
        let off = a[0][1] * a[0][1] + a[0][2] * a[0][2] + a[1][2] * a[1][2];
        let diagonal = a[0][0] * a[0][0] + a[1][1] * a[1][1] + a[2][2] * a[2][2];
        if (off <= 1e-14 * max(diagonal, 1e-30)) {
            break;
        }
        for (var r = 0u; r < 3u; r++) {
            var p = 0u;
            var q = 1u;
            if (r == 1u) {
                q = 2u;
            } else if (r == 2u) {
                p = 1u;
                q = 2u;
            }
            if (abs(a[p][q]) < 1e-30) {
                continue;
            }
            let theta = (a[q][q] - a[p][p]) / (2.0 * a[p][q]);
            var tn = 1.0;
            if (theta != 0.0) {
                tn = sign(theta) / (abs(theta) + sqrt(theta * theta + 1.0));
            }
            let cs = 1.0 / sqrt(tn * tn + 1.0);
            let sn = tn * cs;
            for (var row = 0u; row < 3u; row++) {
                let akp = a[row][p];
                let akq = a[row][q];
                a[row][p] = cs * akp - sn * akq;
                a[row][q] = sn * akp + cs * akq;
            }
            let rp = a[p];
            let rq = a[q];
            for (var col = 0u; col < 3u; col++) {
                a[p][col] = cs * rp[col] - sn * rq[col];
                a[q][col] = sn * rp[col] + cs * rq[col];
            }
            for (var row = 0u; row < 3u; row++) {
                let vp = v[row][p];
                let vq = v[row][q];
                v[row][p] = cs * vp - sn * vq;
                v[row][q] = sn * vp + cs * vq;
            }
        }
    }
    return Eigen(vec3<f32>(a[0][0], a[1][1], a[2][2]), v);
}

// The cell's solid corners' materials blended: the four most frequent, weighted by their
// share, ties to the lower id (`VertexMaterial::blend`); ids and weights a byte each.
fn blend(c: Chunk, cell: vec3<u32>) -> vec2<u32> {
    var ids = array<u32, 8>(0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u);
    var counts = array<u32, 8>(0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u);
    var used = 0u;
    for (var k = 0u; k < 8u; k++) {
        let corner = cell + vec3<u32>(k & 1u, (k >> 1u) & 1u, (k >> 2u) & 1u);
        if (inside(c, corner.x, corner.y, corner.z) == 0u) {
            continue;
        }
        var id = 0u;
        if (c.material_base != 0xffffffffu) {
            let node = corner.x + c.m * (corner.y + c.m * corner.z);
            id = (data[c.material_base + node / 4u] >> (8u * (node % 4u))) & 0xffu;
        }
        var found = false;
        for (var j = 0u; j < used; j++) {
            if (ids[j] == id) {
                counts[j] += 1u;
                found = true;
            }
        }
        if (!found) {
            ids[used] = id;
            counts[used] = 1u;
            used += 1u;
        }
    }
    if (used == 0u) {
        return vec2<u32>(0u, 255u);
    }
    // Sort by count (more first), then id (lower first).
    for (var i = 1u; i < used; i++) {
        var j = i;
        while (j > 0u && (counts[j] > counts[j - 1u] || (counts[j] == counts[j - 1u] && ids[j] < ids[j - 1u]))) {
            let ci = counts[j];
            counts[j] = counts[j - 1u];
            counts[j - 1u] = ci;
            let ii = ids[j];
            ids[j] = ids[j - 1u];
            ids[j - 1u] = ii;
            j -= 1u;
        }
    }
    let top = min(used, 4u);
    var total = 0u;
    for (var j = 0u; j < top; j++) {
        total += counts[j];
    }
    var out_ids = ids[0] * 0x01010101u;
    var out_weights = 0u;
    var given = 0u;
    for (var j = 0u; j < top; j++) {
        out_ids = (out_ids & ~(0xffu << (8u * j))) | (ids[j] << (8u * j));
        var w = counts[j] * 255u / total;
        if (j + 1u == top) {
            w = 255u - given;
        }
        out_weights |= w << (8u * j);
        given += w;
    }
    return vec2<u32>(out_ids, out_weights);
}

@compute @workgroup_size(256)
fn dual_emit(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let k = wg.x;
    let c = chunks[k];
    let run = cell_run(c, t);
    let m3 = c.m * c.m * c.m;
    var at = (scratch[chunk_first_at(k)] + scratch[k * THREADS + t]) * 10u;
    for (var i = run.x; i < run.y; i++) {
        let cell = cell_at(c, i);
        let case_index = case_of(c, cell);
        let components = data[DUAL_TABLE + case_index * 5u];
        // Each cell's first vertex, for the quad passes (a table of n³ words a chunk).
        scratch[c.crossing_base + i] = at / 10u;
        if (components == 0u) {
            continue;
        }
        let material = blend(c, cell);
        for (var comp = 0u; comp < components; comp++) {
            let mask = data[DUAL_TABLE + case_index * 5u + 1u + comp];
            // The QEF of the component's crossings, in the cell's frame.
            var ata = array<array<f32, 3>, 3>(
                array<f32, 3>(0.0, 0.0, 0.0),
                array<f32, 3>(0.0, 0.0, 0.0),
                array<f32, 3>(0.0, 0.0, 0.0),
            );
            var atb = vec3<f32>(0.0);
            var mass = vec3<f32>(0.0);
            var normal_sum = vec3<f32>(0.0);
            var count = 0.0;
            for (var e = 0u; e < 12u; e++) {
                if (((mask >> e) & 1u) == 0u) {
                    continue;
                }
                let axis = e / 4u;
                var off = vec3<u32>(0u);
                off[(axis + 1u) % 3u] = e & 1u;
                off[(axis + 2u) % 3u] = (e >> 1u) & 1u;
                let node = cell + off;
                var base = c.crossing_base;
                if (axis == 1u) {
                    base += c.y_base;
                } else if (axis == 2u) {
                    base += c.z_base;
                }
                let index = base + crossing_index(c, axis, node, m3) - c.crossing_base;
                let pair = c.pair_base + index * 2u;
                var p = vec3<f32>(off);
                p[axis] = p[axis] + bitcast<f32>(data[pair]);
                let n = unpack_normal(data[pair + 1u]);
                for (var r = 0u; r < 3u; r++) {
                    for (var col = 0u; col < 3u; col++) {
                        ata[r][col] += n[r] * n[col];
                    }
                }
                atb += n * dot(n, p);
                mass += p;
                normal_sum += n;
                count += 1.0;
            }
            let centre = mass / max(count, 1.0);
            let a_c = vec3<f32>(
                ata[0][0] * centre.x + ata[0][1] * centre.y + ata[0][2] * centre.z,
                ata[1][0] * centre.x + ata[1][1] * centre.y + ata[1][2] * centre.z,
                ata[2][0] * centre.x + ata[2][1] * centre.y + ata[2][2] * centre.z,
            );
            let rhs = atb - a_c;
            var x = centre;
            let resultant = length(normal_sum);
            if (count > 0.0 && count * (1.0 - resultant / count) < 1.0 - cos(radians(5.7))) {
                // Nearly parallel planes: only the mean normal's direction is kept.
                let mn = normal_sum / resultant;
                let am = vec3<f32>(
                    dot(vec3<f32>(ata[0][0], ata[0][1], ata[0][2]), mn),
                    dot(vec3<f32>(ata[1][0], ata[1][1], ata[1][2]), mn),
                    dot(vec3<f32>(ata[2][0], ata[2][1], ata[2][2]), mn),
                );
                let lambda = dot(mn, am);
                if (lambda > 0.0) {
                    x = centre + mn * (dot(mn, rhs) / lambda);
                }
            } else {
                let eig = symmetric_eigen(ata);
                let largest = max(max(abs(eig.values.x), abs(eig.values.y)), abs(eig.values.z));
                if (largest > 0.0) {
                    var dx = vec3<f32>(0.0);
                    for (var j = 0u; j < 3u; j++) {
                        if (abs(eig.values[j]) > EIGEN_CUTOFF * largest) {
                            let vj = vec3<f32>(eig.v[0][j], eig.v[1][j], eig.v[2][j]);
                            dx += vj * (dot(vj, rhs) / eig.values[j]);
                        }
                    }
                    x = centre + dx;
                }
            }
            let local = clamp(x, vec3<f32>(-CELL_MARGIN), vec3<f32>(1.0 + CELL_MARGIN));
            let position = (vec3<f32>(cell) + local) * c.spacing;
            var normal = vec3<f32>(0.0, 0.0, 1.0);
            if (dot(normal_sum, normal_sum) > 0.0) {
                normal = normalize(normal_sum);
            }
            vertices[at] = i;
            vertices[at + 1u] = mask;
            set_vertex_vec3(at + 2u, position);
            set_vertex_vec3(at + 5u, normal);
            vertices[at + 8u] = material.x;
            vertices[at + 9u] = material.y;
            at += 10u;
        }
    }
}

// ---- Quads (one level): a quad around every sign-changing edge a chunk owns (its lower node
// in the chunk on the two axes across it), joining the vertices of the components that hold the
// edge in the four cells around it (cells before the chunk are its neighbours'); a face between
// two ring cells whose components both run through both of its segments passes through the
// segment's midpoint, and a polygon of more than four vertices is fanned from its centre, as the
// CPU's `DualCache::assemble` does. For a chunk, `seam_base` holds where its six neighbours'
// block numbers (−x, −y, −z, −x−y, −y−z, −z−x; 0xffffffff: not in the batch) start in `data`,
// and `seam_slot` whether it makes quads (1) or only lends its vertices (0).
//
//   quad_count   one workgroup a chunk: each thread's run of crossings: triangles and extra
//                vertices (midpoints, centres), scanned.
//   quad_scan    one workgroup: the chunks' first triangle and first extra vertex.
//   quad_emit    one workgroup a chunk: the triangles (vertex numbers: dual vertices first,
//                then the extra ones), and the extra vertices (ten words each, after the dual
//                ones: 0xffffffff, chunk, position, normal, material).

// Scratch words of the quad passes, after the vertex passes' (per thread: triangles, extras;
// per chunk: triangles, extras; per chunk and one more: first triangle, first extra).
fn quad_thread_at(k: u32, t: u32) -> u32 {
    return params.chunk_count * (THREADS + 2u) + 1u + (k * THREADS + t) * 2u;
}

fn quad_chunk_at(k: u32) -> u32 {
    return params.chunk_count * (THREADS + 2u) + 1u + params.chunk_count * THREADS * 2u + k * 2u;
}

fn quad_first_at(k: u32) -> u32 {
    return params.chunk_count * (THREADS + 2u) + 1u + params.chunk_count * (THREADS + 1u) * 2u + k * 2u;
}

// The number of dual vertices of cell `i` of chunk `k` before component 0 (its first vertex).
fn cell_vertex(k: u32, i: u32) -> u32 {
    // `dual_emit` wrote every cell's first vertex to the chunk's cell table in the scratch
    // (at `crossing_base`, which these passes do not otherwise use).
    return scratch[load_chunk(k).crossing_base + i];
}

// A ring cell: its chunk (in the batch), local cell, component mask, vertex number, offset of its
// chunk (0 or −1 on each axis: one level only); `ok` false where its chunk is not in the batch or no component
// holds the edge.
struct RingCell {
    k: u32,
    cell: vec3<u32>,
    mask: u32,
    vertex: u32,
    shift: vec3<i32>,
    ok: bool,
};

fn neighbour(k: u32, shift: vec3<i32>) -> u32 {
    if (all(shift == vec3<i32>(0))) {
        return k;
    }
    let base = load_chunk(k).seam_base;
    if (params.mixed == 1u) {
        // All 27 offsets, (dx + 1) + 3 (dy + 1) + 9 (dz + 1).
        return data[base + u32(shift.x + 1) + 3u * u32(shift.y + 1) + 9u * u32(shift.z + 1)];
    }
    var slot = 0u;
    if (all(shift == vec3<i32>(-1, 0, 0))) {
        slot = 0u;
    } else if (all(shift == vec3<i32>(0, -1, 0))) {
        slot = 1u;
    } else if (all(shift == vec3<i32>(0, 0, -1))) {
        slot = 2u;
    } else if (all(shift == vec3<i32>(-1, -1, 0))) {
        slot = 3u;
    } else if (all(shift == vec3<i32>(0, -1, -1))) {
        slot = 4u;
    } else {
        slot = 5u;
    }
    return data[base + slot];
}

// The component (x; 0xffffffff: none) of cell `cell` of chunk `c` whose loop holds the cell's
// edge `edge` (a `cell_edge` bit), in the order of the cell's vertices, and its edges (y).
fn component_holding(c: Chunk, cell: vec3<u32>, edge: u32) -> vec2<u32> {
    let case_index = case_of(c, cell);
    let count = data[DUAL_TABLE + case_index * 5u];
    for (var j = 0u; j < count; j++) {
        let mask = data[DUAL_TABLE + case_index * 5u + 1u + j];
        if (((mask >> edge) & 1u) == 1u) {
            return vec2<u32>(j, mask);
        }
    }
    return vec2<u32>(0xffffffffu, 0u);
}

fn ring_cell(k: u32, cell: vec3<i32>, axis: u32, l: vec3<i32>) -> RingCell {
    let n = i32(load_chunk(k).n);
    let shift = vec3<i32>(select(0, -1, cell.x < 0), select(0, -1, cell.y < 0), select(0, -1, cell.z < 0));
    var r = RingCell(0u, vec3<u32>(0u), 0u, 0u, shift, false);
    let kk = neighbour(k, shift);
    if (kk == 0xffffffffu) {
        return r;
    }
    let local = vec3<u32>(cell - shift * n);
    let c = load_chunk(kk);
    let found = component_holding(c, local, cell_edge(axis, vec3<u32>(l - cell)));
    if (found.x == 0xffffffffu) {
        return r;
    }
    let index = local.x + c.n * (local.y + c.n * local.z);
    return RingCell(kk, local, found.y, cell_vertex(kk, index) + found.x, shift, true);
}

// The cell-edge bits of the face with normal `fa` at `side` (the CPU's `face_edges`).
fn face_edges(fa: u32, side: u32) -> u32 {
    var bits = 0u;
    for (var q = 1u; q <= 2u; q++) {
        let axis = (fa + q) % 3u;
        let other = 3u - fa - axis;
        for (var o = 0u; o < 2u; o++) {
            var off = vec3<u32>(0u);
            off[fa] = side;
            off[other] = o;
            bits |= 1u << (4u * axis + off[(axis + 1u) % 3u] + 2u * off[(axis + 2u) % 3u]);
        }
    }
    return bits;
}

// Where crossing (axis, node) of chunk `c` lies, chunk-local grid units.
fn crossing_point(c: Chunk, axis: u32, node: vec3<u32>) -> vec3<f32> {
    let m3 = c.m * c.m * c.m;
    var base = 0u;
    if (axis == 1u) {
        base = c.y_base;
    } else if (axis == 2u) {
        base = c.z_base;
    }
    let index = base + crossing_index(c, axis, node, m3);
    var p = vec3<f32>(node);
    p[axis] = p[axis] + bitcast<f32>(data[c.pair_base + index * 2u]);
    return p * c.spacing;
}

// A dual vertex's position, normal and material words, in the frame of the chunk shifted by
// `shift` from it.
fn dual_position(v: u32, shift: vec3<i32>) -> vec3<f32> {
    let at = v * 10u;
    return vertex_vec3(at + 2u) + vec3<f32>(shift) * 16.0;
}

// The polygon around owned crossing `i` of chunk `k` (0 vertices where it has none).
struct Polygon {
    count: u32,
    // Up to eight: dual vertex numbers, or 0x80000000 | midpoint slot (corner, lo ring index).
    v: array<u32, 8>,
    // Per midpoint: the lo ring cell's chunk, local cell, face axis, corner, the ring pair.
    mid: array<vec4<u32>, 4>,
    mid_cell: array<vec3<u32>, 4>,
    mid_shift: array<vec3<i32>, 4>,
    mids: u32,
    inside: bool,
};

// Crossing `i` of chunk `c` (x crossings, then y, then z): its lower node and its axis (w).
fn owned_crossing(c: Chunk, i: u32) -> vec4<u32> {
    var axis = 0u;
    var index = i;
    if (i >= c.z_base) {
        axis = 2u;
        index = i - c.z_base;
    } else if (i >= c.y_base) {
        axis = 1u;
        index = i - c.y_base;
    }
    return vec4<u32>(crossing_lower(c, axis, index), axis);
}

fn polygon_of(k: u32, i: u32) -> Polygon {
    var out: Polygon;
    out.count = 0u;
    out.mids = 0u;
    let c = load_chunk(k);
    if (c.seam_slot != 1u) {
        return out;
    }
    // Crossing i of the chunk: its axis and lower node (by rank: find it on its line).
    let found = owned_crossing(c, i);
    let axis = found.w;
    let lower = found.xyz;
    if (params.mixed == 1u) {
        return mixed_polygon(k, c, axis, lower);
    }
    let u = (axis + 1u) % 3u;
    let v = (axis + 2u) % 3u;
    if (lower[u] >= c.n || lower[v] >= c.n) {
        return out;
    }
    let l = vec3<i32>(lower);
    var eu = vec3<i32>(0);
    eu[u] = 1;
    var ev = vec3<i32>(0);
    ev[v] = 1;
    let ring = array<vec3<i32>, 4>(l - eu - ev, l - ev, l, l - eu);
    var cells: array<RingCell, 4>;
    for (var q = 0u; q < 4u; q++) {
        cells[q] = ring_cell(k, ring[q], axis, l);
        if (!cells[q].ok) {
            return out;
        }
    }
    out.inside = inside(c, lower.x, lower.y, lower.z) == 1u;
    for (var q = 0u; q < 4u; q++) {
        out.v[out.count] = cells[q].vertex;
        out.count += 1u;
        let j = (q + 1u) % 4u;
        var fa = 0u;
        for (var a = 0u; a < 3u; a++) {
            if (ring[q][a] != ring[j][a]) {
                fa = a;
            }
        }
        var lo = q;
        var hi = j;
        if (ring[q][fa] > ring[j][fa]) {
            lo = j;
            hi = q;
        }
        if ((cells[lo].mask & face_edges(fa, 1u)) != face_edges(fa, 1u)
            || (cells[hi].mask & face_edges(fa, 0u)) != face_edges(fa, 0u)) {
            continue;
        }
        var inside_end = l;
        if (!out.inside) {
            inside_end = l + vec3<i32>(select(0, 1, axis == 0u), select(0, 1, axis == 1u), select(0, 1, axis == 2u));
        }
        let cu = u32(inside_end[(fa + 1u) % 3u] - ring[lo][(fa + 1u) % 3u]);
        let cv = u32(inside_end[(fa + 2u) % 3u] - ring[lo][(fa + 2u) % 3u]);
        out.mid[out.mids] = vec4<u32>(cells[lo].k, fa, cu + 2u * cv, q);
        out.mid_cell[out.mids] = cells[lo].cell;
        out.mid_shift[out.mids] = cells[lo].shift;
        out.v[out.count] = 0x80000000u | out.mids;
        out.mids += 1u;
        out.count += 1u;
    }
    return out;
}

// The lower node of the `index`-th crossing along `axis` of chunk `c` (its rank order: lines in
// `Axis::across` order, then along the line).
fn crossing_lower(c: Chunk, axis: u32, index: u32) -> vec3<u32> {
    // Binary search over the lines' first crossings.
    let stride = 1u + c.words;
    let base = c.rows_base + axis * c.m * c.m * stride;
    var lo = 0u;
    var hi = c.m * c.m;
    while (hi - lo > 1u) {
        let mid = (lo + hi) / 2u;
        if (data[base + mid * stride] <= index) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    // The crossing's position along the line: the (index − first)-th set bit.
    var left = index - data[base + lo * stride];
    var e = 0u;
    for (var w = 0u; w < c.words; w++) {
        var bits = data[base + lo * stride + 1u + w];
        let ones = countOneBits(bits);
        if (left < ones) {
            for (var s = 0u; s < left; s++) {
                bits &= bits - 1u;
            }
            e = 32u * w + firstTrailingBit(bits);
            break;
        }
        left -= ones;
    }
    let line_u = lo % c.m;
    let line_v = lo / c.m;
    var node = vec3<u32>(0u);
    node[axis] = e;
    node[(axis + 1u) % 3u] = line_u;
    node[(axis + 2u) % 3u] = line_v;
    return node;
}

// Triangles and extra vertices a polygon makes.
fn polygon_counts(p: Polygon) -> vec2<u32> {
    if (p.count == 0u) {
        return vec2<u32>(0u);
    }
    if (p.count == 3u) {
        return vec2<u32>(1u, 0u);
    }
    if (p.count == 4u) {
        return vec2<u32>(2u, 0u);
    }
    return vec2<u32>(p.count, p.mids + 1u);
}

// A chunk's crossings (kept in `centroid_first` for these passes).
fn crossing_total(c: Chunk) -> u32 {
    return c.centroid_first;
}

// Chunk `k` as the quad passes read it: from `data` at `seam_list_base` (20 words a chunk), so
// that they bind four storage buffers at most.
fn load_chunk(k: u32) -> Chunk {
    let b = params.seam_list_base + k * 20u;
    return Chunk(data[b], data[b + 1u], data[b + 2u], data[b + 3u], data[b + 4u], data[b + 5u], data[b + 6u],
        data[b + 7u], bitcast<f32>(data[b + 8u]), data[b + 9u], data[b + 10u], data[b + 11u], data[b + 12u],
        data[b + 13u], data[b + 14u], data[b + 15u], data[b + 16u], data[b + 17u], data[b + 18u], data[b + 19u]);
}

fn crossing_run(c: Chunk, t: u32) -> vec2<u32> {
    let total = crossing_total(c);
    let per = (total + THREADS - 1u) / THREADS;
    return vec2<u32>(min(total, t * per), min(total, (t + 1u) * per));
}

@compute @workgroup_size(256)
fn quad_count(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let k = wg.x;
    let run = crossing_run(load_chunk(k), t);
    var counts = vec2<u32>(0u);
    for (var i = run.x; i < run.y; i++) {
        counts += polygon_counts(polygon_of(k, i));
    }
    let first_triangle = scan(t, counts.x);
    let triangles = sums[THREADS - 1u];
    workgroupBarrier();
    let first_extra = scan(t, counts.y);
    let extras = sums[THREADS - 1u];
    scratch[quad_thread_at(k, t)] = first_triangle;
    scratch[quad_thread_at(k, t) + 1u] = first_extra;
    if (t == 0u) {
        scratch[quad_chunk_at(k)] = triangles;
        scratch[quad_chunk_at(k) + 1u] = extras;
    }
}

@compute @workgroup_size(256)
fn quad_scan(@builtin(local_invocation_index) t: u32) {
    let count = params.chunk_count;
    for (var part = 0u; part < 2u; part++) {
        var carry = 0u;
        for (var start = 0u; start < count; start += THREADS) {
            let i = start + t;
            var value = 0u;
            if (i < count) {
                value = scratch[quad_chunk_at(i) + part];
            }
            let first = scan(t, value);
            if (i < count) {
                scratch[quad_first_at(i) + part] = carry + first;
            }
            carry += sums[THREADS - 1u];
            workgroupBarrier();
        }
        if (t == 0u) {
            scratch[quad_first_at(count) + part] = carry;
        }
        workgroupBarrier();
    }
}

// Writes extra vertex `e` (ten words, after the dual vertices).
fn write_extra(e: u32, k: u32, p: vec3<f32>, n: vec3<f32>, ids: u32, weights: u32) {
    let at = (scratch[chunk_first_at(params.chunk_count)] + e) * 10u;
    vertices[at] = 0xffffffffu;
    vertices[at + 1u] = k;
    set_vertex_vec3(at + 2u, p);
    set_vertex_vec3(at + 5u, n);
    vertices[at + 8u] = ids;
    vertices[at + 9u] = weights;
}

fn vertex_normal(v: u32) -> vec3<f32> {
    let at = v * 10u;
    return vertex_vec3(at + 5u);
}

@compute @workgroup_size(256)
fn quad_emit(@builtin(workgroup_id) wg: vec3<u32>, @builtin(local_invocation_index) t: u32) {
    let k = wg.x;
    let run = crossing_run(load_chunk(k), t);
    var tri = (scratch[quad_first_at(k)] + scratch[quad_thread_at(k, t)]) * 3u;
    var extra = scratch[quad_first_at(k) + 1u] + scratch[quad_thread_at(k, t) + 1u];
    let dual_total = scratch[chunk_first_at(params.chunk_count)];
    for (var i = run.x; i < run.y; i++) {
        let p = polygon_of(k, i);
        if (p.count == 0u) {
            continue;
        }
        // The polygon's vertex numbers and positions in this chunk's frame.
        var ids = array<u32, 8>(0u, 0u, 0u, 0u, 0u, 0u, 0u, 0u);
        var pos: array<vec3<f32>, 8>;
        var nor: array<vec3<f32>, 8>;
        var q = array<u32, 4>(0u, 0u, 0u, 0u);
        var qn = 0u;
        for (var j = 0u; j < p.count; j++) {
            let v = p.v[j];
            if ((v & 0x80000000u) == 0u) {
                ids[j] = v;
                // The vertex's chunk shift: look it up from the ring (dual vertices carry their
                // cell, not their chunk), by the chunk that owns the vertex number.
                pos[j] = dual_position(v, vertex_shift(k, v));
                nor[j] = vertex_normal(v);
                q[qn] = j;
                qn += 1u;
            }
        }
        for (var j = 0u; j < p.count; j++) {
            let v = p.v[j];
            if ((v & 0x80000000u) != 0u) {
                let m = p.mid[v & 0xffu];
                let cc = load_chunk(m.x);
                let fa = m.y;
                let corner = m.z;
                let fu = (fa + 1u) % 3u;
                let fv = (fa + 2u) % 3u;
                var base = p.mid_cell[v & 0xffu];
                base[fa] += 1u;
                var e_u = base;
                e_u[fv] += corner >> 1u;
                var e_v = base;
                e_v[fu] += corner & 1u;
                let mid = (crossing_point(cc, fu, e_u) + crossing_point(cc, fv, e_v)) * 0.5
                    + vec3<f32>(p.mid_shift[v & 0xffu]) * 16.0;
                // Between ring vertices a and b (the ones before and after it).
                let a = ids[(j + p.count - 1u) % p.count];
                let b = ids[(j + 1u) % p.count];
                let n = normalize_or_z(vertex_normal(a) + vertex_normal(b));
                let mat = vertices[a * 10u + 8u];
                let wts = vertices[a * 10u + 9u];
                write_extra(extra, k, mid, n, mat, wts);
                ids[j] = dual_total + extra;
                pos[j] = mid;
                nor[j] = n;
                extra += 1u;
            }
        }
        // Outward is +axis when the lower node is inside.
        var order = array<u32, 8>(0u, 1u, 2u, 3u, 4u, 5u, 6u, 7u);
        if (!p.inside) {
            for (var j = 0u; j < p.count; j++) {
                order[j] = p.count - 1u - j;
            }
        }
        if (p.count == 4u) {
            // Split along the flatter diagonal (the CPU's `push_quad`).
            let a = pos[order[0]];
            let b = pos[order[1]];
            let c2 = pos[order[2]];
            let d = pos[order[3]];
            let f0 = dot(normalize_or_zero(cross(b - a, c2 - a)), normalize_or_zero(cross(c2 - a, d - a)));
            let f1 = dot(normalize_or_zero(cross(c2 - b, d - b)), normalize_or_zero(cross(d - b, a - b)));
            var s = array<u32, 6>(0u, 1u, 2u, 0u, 2u, 3u);
            if (f0 < f1) {
                s = array<u32, 6>(1u, 2u, 3u, 1u, 3u, 0u);
            }
            for (var j = 0u; j < 6u; j++) {
                indices[tri + j] = ids[order[s[j]]];
            }
            tri += 6u;
        } else if (p.count == 3u) {
            // A coarser cell holds two of the ring's cells (across levels): one triangle.
            for (var j = 0u; j < 3u; j++) {
                indices[tri + j] = ids[order[j]];
            }
            tri += 3u;
        } else {
            var centre = vec3<f32>(0.0);
            var normal = vec3<f32>(0.0);
            for (var j = 0u; j < p.count; j++) {
                centre += pos[order[j]];
                normal += nor[order[j]];
            }
            centre = centre / f32(p.count);
            // The material of the ring's first vertex after the turn (the CPU's `q[0]`).
            var qa = ids[q[0]];
            if (!p.inside) {
                qa = ids[q[3]];
            }
            write_extra(extra, k, centre, normalize_or_z(normal), vertices[qa * 10u + 8u], vertices[qa * 10u + 9u]);
            let c = dual_total + extra;
            extra += 1u;
            for (var j = 0u; j < p.count; j++) {
                indices[tri] = c;
                indices[tri + 1u] = ids[order[j]];
                indices[tri + 2u] = ids[order[(j + 1u) % p.count]];
                tri += 3u;
            }
        }
    }
}

fn normalize_or_zero(v: vec3<f32>) -> vec3<f32> {
    let l = dot(v, v);
    if (l > 0.0) {
        return v * inverseSqrt(l);
    }
    return vec3<f32>(0.0);
}

fn normalize_or_z(v: vec3<f32>) -> vec3<f32> {
    let l = dot(v, v);
    if (l > 0.0) {
        return v * inverseSqrt(l);
    }
    return vec3<f32>(0.0, 0.0, 1.0);
}

// The shift (0 or −1 a component at one level, −1, 0 or 1 across levels) of the chunk whose
// dual vertex `v` is, from chunk `k`: the chunk of the batch whose vertices hold it, compared
// with `k`'s neighbours.
fn vertex_shift(k: u32, v: u32) -> vec3<i32> {
    var lo = 0u;
    var hi = params.chunk_count;
    while (hi - lo > 1u) {
        let mid = (lo + hi) / 2u;
        if (scratch[chunk_first_at(mid)] <= v) {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    if (lo == k) {
        return vec3<i32>(0);
    }
    let base = load_chunk(k).seam_base;
    if (params.mixed == 1u) {
        for (var s = 0u; s < 27u; s++) {
            if (data[base + s] == lo) {
                return vec3<i32>(i32(s % 3u) - 1, i32((s / 3u) % 3u) - 1, i32(s / 9u) - 1);
            }
        }
        return vec3<i32>(0);
    }
    let shifts = array<vec3<i32>, 6>(
        vec3<i32>(-1, 0, 0), vec3<i32>(0, -1, 0), vec3<i32>(0, 0, -1),
        vec3<i32>(-1, -1, 0), vec3<i32>(0, -1, -1), vec3<i32>(-1, 0, -1),
    );
    for (var s = 0u; s < 6u; s++) {
        if (data[base + s] == lo) {
            return shifts[s];
        }
    }
    return vec3<i32>(0);
}

// ---- Quads across levels (`params.mixed`), as the CPU's `DualCache::assemble_mixed` joins a
// volume whose chunks differ in level: every sign-changing edge of a chunk's own level (those
// on its `+` faces too) whose four cells around it are of that level or coarser, and whose
// finest chunk of (+,+), (−,+), (+,−), (−,−) is this one, joins the vertices of the components
// holding it in those cells, each in whichever chunk holds it at that chunk's level; a finer
// edge inside a coarser cell's face takes the component of the face segment that cuts it. A
// coarser cell holding two of the cells makes a triangle of the polygon. No midpoints, no
// centres. A chunk's neighbour table holds all 27 offsets here.
//
// Positions are exact integers in sixteenths of a grid unit (a chunk is 256 of them, a cell
// 4, 8 or 16): the CPU's points a hundredth of a finest cell beside the edge's middle are one
// sixteenth beside it here, inside the same cells.

fn floor_div(a: i32, b: i32) -> i32 {
    let q = a / b;
    return select(q, q - 1, (a % b) != 0 && a < 0);
}

fn floor_div3(a: vec3<i32>, b: i32) -> vec3<i32> {
    return vec3<i32>(floor_div(a.x, b), floor_div(a.y, b), floor_div(a.z, b));
}

// Cell edge bit of the edge along `axis` at `off` (0 or 1 across) from the cell's least corner.
fn cell_edge(axis: u32, off: vec3<u32>) -> u32 {
    return 4u * axis + off[(axis + 1u) % 3u] + 2u * off[(axis + 2u) % 3u];
}

// The corner of a cell's face (normal `fa`, at `side`) whose two face edges `mask` holds: its
// offsets along the face's first and second axes (the CPU's `corner_of`).
fn face_corner(mask: u32, fa: u32, side: u32) -> vec2<u32> {
    let fu = (fa + 1u) % 3u;
    let fv = (fa + 2u) % 3u;
    var corner = vec2<u32>(0u);
    for (var o = 0u; o < 2u; o++) {
        var off = vec3<u32>(0u);
        off[fa] = side;
        off[fv] = o;
        if (((mask >> cell_edge(fu, off)) & 1u) == 1u) {
            corner.y = o;
        }
        var off2 = vec3<u32>(0u);
        off2[fa] = side;
        off2[fu] = o;
        if (((mask >> cell_edge(fv, off2)) & 1u) == 1u) {
            corner.x = o;
        }
    }
    return corner;
}

// The component (0xffffffff: none) of cell `cell` of chunk `c` (its cells `size` sixteenths a
// side) whose edges on the face with normal `fa` at `side` hold the face segment a finer edge
// inside that face belongs to, the finer edge's inside end at `inside_end` (sixteenths from the
// cell's least corner): the one component on the face, or of several the first whose segment's
// corner lies within a cell (L1) of that end (the CPU's `ChunkDual::vertex_on_face`).
fn component_on_face(c: Chunk, cell: vec3<u32>, fa: u32, side: u32, inside_end: vec3<i32>, size: i32) -> u32 {
    let face = face_edges(fa, side);
    let case_index = case_of(c, cell);
    let count = data[DUAL_TABLE + case_index * 5u];
    var first = 0xffffffffu;
    var on_face = 0u;
    for (var j = 0u; j < count; j++) {
        if ((data[DUAL_TABLE + case_index * 5u + 1u + j] & face) != 0u) {
            if (on_face == 0u) {
                first = j;
            }
            on_face += 1u;
        }
    }
    if (on_face < 2u) {
        return first;
    }
    let fu = (fa + 1u) % 3u;
    let fv = (fa + 2u) % 3u;
    for (var j = 0u; j < count; j++) {
        let mask = data[DUAL_TABLE + case_index * 5u + 1u + j] & face;
        if (mask == 0u) {
            continue;
        }
        let corner = vec2<i32>(face_corner(mask, fa, side)) * size;
        if (abs(inside_end[fu] - corner.x) + abs(inside_end[fv] - corner.y) < size) {
            return j;
        }
    }
    return 0xffffffffu;
}

// The polygon across levels around the crossing along `axis` from node `lower` of chunk `k`
// (`c`), which makes quads.
fn mixed_polygon(k: u32, c: Chunk, axis: u32, lower: vec3<u32>) -> Polygon {
    var out: Polygon;
    out.count = 0u;
    out.mids = 0u;
    let u = (axis + 1u) % 3u;
    let v = (axis + 2u) % 3u;
    let own = i32(round(c.spacing * 16.0));
    var along = vec3<i32>(0);
    along[axis] = 1;
    // The edge's ends, sixteenths in this chunk's frame.
    let e0 = vec3<i32>(lower) * own;
    let e1 = e0 + along * own;
    // The four cells around it, counter-clockwise around +axis: (−,−), (+,−), (+,+), (−,+).
    let su = array<i32, 4>(-1, 1, 1, -1);
    let sv = array<i32, 4>(-1, -1, 1, 1);
    var points: array<vec3<i32>, 4>;
    var chunks: array<u32, 4>;
    var shifts: array<vec3<i32>, 4>;
    var sizes: array<i32, 4>;
    var finest = 1000;
    for (var q = 0u; q < 4u; q++) {
        // The point beside the edge's middle in this quadrant.
        var p = e0 + along * (own / 2);
        p[u] += su[q];
        p[v] += sv[q];
        points[q] = p;
        let shift = floor_div3(p, 256);
        let kk = neighbour(k, shift);
        if (kk == 0xffffffffu) {
            return out;
        }
        chunks[q] = kk;
        shifts[q] = shift;
        sizes[q] = i32(round(load_chunk(kk).spacing * 16.0));
        finest = min(finest, sizes[q]);
    }
    if (finest != own) {
        return out;
    }
    // The finest chunk around the edge owns it: of several, the first of (+,+), (−,+), (+,−),
    // (−,−).
    let order = array<u32, 4>(2u, 3u, 1u, 0u);
    for (var o = 0u; o < 4u; o++) {
        let q = order[o];
        if (sizes[q] == finest) {
            if (chunks[q] != k) {
                return out;
            }
            break;
        }
    }
    let lower_inside = inside(c, lower.x, lower.y, lower.z) == 1u;
    for (var q = 0u; q < 4u; q++) {
        let kk = chunks[q];
        let cc = load_chunk(kk);
        let size = sizes[q];
        let frame = shifts[q] * 256;
        let cell = floor_div3(points[q] - frame, size);
        // The edge's ends from the cell's least corner (sixteenths).
        let r0 = e0 - frame - cell * size;
        let r1 = e1 - frame - cell * size;
        let on_u = r0[u] == 0 || r0[u] == size;
        let on_v = r0[v] == 0 || r0[v] == size;
        var j = 0xffffffffu;
        let local = vec3<u32>(cell);
        if (on_u && on_v) {
            j = component_holding(cc, local, cell_edge(axis, vec3<u32>(r0 / size))).x;
        } else {
            // Inside a face of a coarser cell: the face across the first axis it lies on.
            let fa = select(u, v, on_v);
            let side = u32(r0[fa] / size);
            j = component_on_face(cc, local, fa, side, select(r1, r0, lower_inside), size);
        }
        if (j == 0xffffffffu) {
            return out;
        }
        let vertex = cell_vertex(kk, local.x + cc.n * (local.y + cc.n * local.z)) + j;
        if (out.count == 0u || out.v[out.count - 1u] != vertex) {
            out.v[out.count] = vertex;
            out.count += 1u;
        }
    }
    if (out.count > 1u && out.v[0] == out.v[out.count - 1u]) {
        out.count -= 1u;
    }
    if (out.count < 3u) {
        out.count = 0u;
        return out;
    }
    out.inside = lower_inside;
    return out;
}

// ---- Drawing dual contouring where it was made (`GpuMarcher::mesh_dual_for_drawing`): the
// renderer's vertices from the dual and extra vertices, placed by their chunk's placement (a
// dual vertex by the chunk whose cell it is, an extra one by the chunk it was made for), and
// each chunk's indirect arguments for its quads' triangles and their lines (`edge_lines`).

@compute @workgroup_size(64)
fn dual_world(@builtin(global_invocation_id) g: vec3<u32>) {
    let i = g.x + g.y * params.place_row;
    let dual_total = scratch[chunk_first_at(params.chunk_count)];
    let extra_total = scratch[quad_first_at(params.chunk_count) + 1u];
    if (i >= dual_total + extra_total) {
        return;
    }
    var k = 0u;
    if (i < dual_total) {
        var hi = params.chunk_count;
        while (hi - k > 1u) {
            let mid = (k + hi) / 2u;
            if (scratch[chunk_first_at(mid)] <= i) {
                k = mid;
            } else {
                hi = mid;
            }
        }
    } else {
        k = vertices[i * 10u + 1u];
    }
    let at = i * 10u;
    // The blend of the cell's corners, as the CPU's dual contouring gives it.
    write_drawn(i * 12u, placements[k], vertex_vec3(at + 2u), vertex_vec3(at + 5u), vertices[at + 8u], vertices[at + 9u]);
}

@compute @workgroup_size(64)
fn dual_args(@builtin(global_invocation_id) g: vec3<u32>) {
    let k = g.x;
    if (k >= params.chunk_count) {
        return;
    }
    let first = scratch[quad_first_at(k)];
    write_args(k, first, scratch[quad_first_at(k + 1u)] - first);
}
