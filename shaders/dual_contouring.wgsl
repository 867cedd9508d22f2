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
//                 edges, position, normal, material ids, weights).
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
            vertices[at] = bitcast<f32>(i);
            vertices[at + 1u] = bitcast<f32>(mask);
            vertices[at + 2u] = position.x;
            vertices[at + 3u] = position.y;
            vertices[at + 4u] = position.z;
            vertices[at + 5u] = normal.x;
            vertices[at + 6u] = normal.y;
            vertices[at + 7u] = normal.z;
            vertices[at + 8u] = bitcast<f32>(material.x);
            vertices[at + 9u] = bitcast<f32>(material.y);
            at += 10u;
        }
    }
}
