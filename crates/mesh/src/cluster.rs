//! Vertex clustering of a closed candidate mesh, verified exactly: the clustering of regularised
//! marching tetrahedra.
//!
//! The caller names a cluster for every vertex (for the tetrahedra mesher: the lattice node the
//! vertex is nearest to) and marks the vertices that must stay as they are (shared with another
//! chunk). Each cluster becomes one vertex, placed by the QEF of its members' tangent planes;
//! every candidate triangle is carried through the clustering and dropped when two of its corners
//! fall together. That is one linear pass, with no collapse order and no per-collapse test.
//!
//! A clustered mesh can be clustered again (the short-edge rounds): each vertex then carries the
//! candidates it stands for ([`Samples`]), and placement and bounds use those, so every candidate
//! stays within the bounds of its final vertex, not only of an intermediate one.
//!
//! Safety is then verified on the result, not assumed: a cluster is taken apart again (its
//! members kept as they were) when
//!
//! - its members are not joined by the mesh's edges among themselves (it would join separate
//!   pieces or sheets, or let a small piece vanish into a cluster holding another surface);
//! - a member lies farther than [`MAX_MOVE_CELLS`] from the merged vertex's tangent plane, farther
//!   than [`MAX_REACH_CELLS`] from the merged vertex (for the short-edge rounds, their own
//!   bound), or faces away from the cluster's mean normal (the two sides of a sheet thinner than
//!   a cell never merge), or none lies within [`MAX_REACH_CELLS`] of it. The vertex goes where
//!   its members' tangent planes meet (a crease or a corner stays sharp), or where that strays,
//!   halfway to their mean or at their mean (chamfered as the candidates are);
//! - a triangle it belongs to turns over or collapses to no area, or cuts away from the surface
//!   (its centroid or an edge midpoint farther than [`MAX_CHORD_CELLS`] from all three corners'
//!   tangent planes: a chord across a tip or a groove narrower than a cell);
//! - a vertex it belongs to, or one beside it, has a link (the triangles around it, each seen as
//!   the directed edge opposite the vertex) that is not one simple cycle of at least three edges,
//!   or for a vertex that stays, not one simple path or cycle;
//! - a candidate triangle folds onto an edge (two of its corners fall together) that is no edge
//!   of the clustered surface;
//! - in a mesh clustered again, a candidate lies farther than [`MAX_REACH_CELLS`] from its vertex
//!   and from every triangle around it (a tip or a fin cut short), where the vertex or one beside
//!   it belongs to the cluster; given the candidate triangles, so does an edge midpoint or the
//!   centroid of a candidate triangle with such a corner (checked once the rest holds; a
//!   concave crease, a box's top face meeting a sphere 0.06 cells under a node plane, had one
//!   0.504 cells from the surface).
//!
//! **Distance.** The clustering maps each candidate vertex to its cluster's vertex and each
//! candidate triangle linearly onto the triangle, edge or vertex its corners go to. A point of a
//! candidate triangle is a weighted mean of its corners, and its image the same mean of theirs,
//! so the two lie no farther apart than the farthest corner from its cluster's vertex. Every
//! clustered triangle is the image of a candidate triangle, and every candidate triangle's image
//! lies on the clustered surface (a folded one's edge is kept, a collapsed one's vertex keeps
//! triangles), so each surface lies within [`MAX_REACH_CELLS`] of the other (their Hausdorff
//! distance) wherever every candidate stays that near its vertex: always for the node clusters,
//! a proof. The short-edge rounds let a pair reach farther (a pair's candidates span two nodes);
//! there a candidate beyond the bound, and the midpoints and centroids of the candidate
//! triangles around it, are only checked against the triangles around its vertex, and the
//! vertex placed within the bound of some candidate. That holds the candidates and the
//! vertices themselves, not every point of the triangles between them: for the rounds the
//! half-cell distance is measured (the random-edit property test, at vertices, edge midpoints and
//! centroids), not proven.
//!
//! Every vertex's link being one simple cycle is exactly a closed, consistently oriented,
//! vertex- and edge-manifold surface: each edge `v–a` then has one triangle that runs `v → a` and
//! one that runs `a → v`, and the triangles around `v` form one disk. A vertex that stays lies on
//! a chunk face; its triangles on this side form a path whose two ends, the edges in the face,
//! clustering never touches (their corners stay), so the paths of the chunks around it still
//! close into one cycle. The checks repeat until nothing is taken apart. They terminate and
//! always succeed: a vertex whose cluster and whose neighbours' clusters are all taken apart has
//! exactly its candidate triangles around it, whose link is a cycle because the candidate mesh
//! is closed and manifold; so every failing check names at least one cluster still whole, and at
//! worst every cluster is taken apart and the candidate mesh comes back unchanged. A folded
//! triangle has two corners in one cluster, which is merged; the far-candidate check looks only
//! at vertices that moved or have a neighbour that did (the others keep the triangles that passed
//! it when they were made) and marks those.

use glam::Vec3;
use smallvec::SmallVec;

use crate::qef::Qef;

const NONE: u32 = u32::MAX;

/// A one-entry list standing for a vertex's own sample.
static NO_LIST: u32 = 0;

/// No member is merged into a vertex whose tangent plane is farther than this (cells) from it.
pub const MAX_MOVE_CELLS: f32 = 0.35;

/// Nor into a vertex farther than this (cells). With 0.75 the bunny's ear tips (at 64 cells)
/// were cut by 0.63 cells; with 0.6 a cube's corner under random CSG edits stood 0.56 cells
/// from the unclustered mesh. Every point of a node-clustered triangle is a weighted mean of its
/// corners, each within this distance of the candidates it stands for, so the clustered surface
/// stays within it of the candidate one (see the module's notes; the short-edge rounds are
/// checked, not bounded, by it).
pub const MAX_REACH_CELLS: f32 = 0.5;

/// No clustered triangle's centroid or edge midpoint lies farther than this (cells) from every
/// corner's tangent plane.
pub const MAX_CHORD_CELLS: f32 = 0.3;

/// The clustering of a candidate mesh.
pub(crate) struct Clustering<'a> {
    /// Candidate positions and unit normals.
    positions: &'a [[f32; 3]],
    normals: &'a [[f32; 3]],
    /// Candidate triangles (a closed, manifold, consistently oriented surface, apart from the
    /// edges between vertices that stay).
    tris: &'a [[u32; 3]],
    /// Vertices that stay as they are.
    locked: &'a [bool],
    /// The cell size in the mesh's units.
    cell: f32,
    /// With a value, a cluster also stays together only if its members' tangent planes pass
    /// within this root-mean-square distance of the merged vertex.
    max_rms: Option<f32>,
    /// For a mesh that is itself clustered: the candidates (positions, normals) each of its
    /// vertices stands for. Placement and bounds then use those, so clustering again keeps
    /// every candidate within the bounds of its final vertex, not only of an intermediate one.
    hermite: Option<Hermite<'a>>,
    /// With a value, the candidate triangles: the far-candidate check then also holds their
    /// edge midpoints and centroids to the bound ([`Clustering::check_far_triangles`]).
    candidate_tris: Option<&'a [[u32; 3]]>,
    /// How far (cells) a member may lie from the merged vertex, and from its tangent plane.
    reach: f32,
    off: f32,
    /// With a value, the side (chunk) each candidate triangle comes from: every vertex's
    /// triangles of each side must then form one simple path or cycle (see [`Clustering::with_sides`]).
    sides: Option<&'a [u8]>,
    /// With a value, clusters already made elsewhere: `pin[v]` is an index into the places, or
    /// `NONE` (see [`Clustering::with_pins`]).
    pins: Option<Pins<'a>>,
    /// With a value `(axis, step)`: merged vertices are placed on multiples of `step` along
    /// `axis` (see [`Clustering::with_snap`]).
    snap: Option<(usize, f32)>,
}

/// For each candidate vertex, `NONE` or the index of its pinned cluster's place (position,
/// normal).
pub(crate) type Pins<'a> = (&'a [u32], &'a [([f32; 3], [f32; 3])]);

/// Candidate positions and normals, and the candidates each vertex stands for.
type Hermite<'a> = (&'a [[f32; 3]], &'a [[f32; 3]], &'a Samples);

/// The candidates each vertex of a clustered mesh stands for: those of vertex `i` are
/// `list[start[i]..start[i + 1]]`; `far[i]` says whether one of them lies farther than
/// [`MAX_REACH_CELLS`] from the vertex.
#[derive(Clone, Debug, Default)]
pub(crate) struct Samples {
    start: Vec<u32>,
    list: Vec<u32>,
    far: Vec<bool>,
}

impl Samples {
    /// The candidates vertex `v` stands for.
    pub(crate) fn of(&self, v: u32) -> &[u32] {
        &self.list[self.start[v as usize] as usize..self.start[v as usize + 1] as usize]
    }
}

/// The clustered mesh: positions, normals, triangles, and for each output vertex the candidate
/// vertex standing for its cluster.
pub(crate) struct Clustered {
    pub positions: Vec<[f32; 3]>,
    pub normals: Vec<[f32; 3]>,
    pub tris: Vec<[u32; 3]>,
    pub kept: Vec<u32>,
    pub samples: Samples,
}

impl<'a> Clustering<'a> {
    /// Keeps a cluster together only if its members' tangent planes pass within `max` (the
    /// mesh's units, root mean square) of the merged vertex.
    pub(crate) fn with_max_rms(mut self, max: f32) -> Self {
        self.max_rms = Some(max);
        self
    }

    /// Lets members lie up to `reach` cells from the merged vertex and `off` cells from its
    /// tangent plane (instead of [`MAX_REACH_CELLS`] and [`MAX_MOVE_CELLS`]).
    pub(crate) fn with_bounds(mut self, reach: f32, off: f32) -> Self {
        self.reach = reach;
        self.off = off;
        self
    }

    /// Places and bounds clusters by the candidates `samples` says each vertex stands for
    /// (`positions` and `normals` are the candidates').
    pub(crate) fn with_samples(
        mut self,
        positions: &'a [[f32; 3]],
        normals: &'a [[f32; 3]],
        samples: &'a Samples,
    ) -> Self {
        self.hermite = Some((positions, normals, samples));
        self
    }

    /// Holds the edge midpoints and centroids of the candidate triangles around a far candidate
    /// to the bound too (see [`Clustering::check_far_triangles`]).
    pub(crate) fn with_candidate_tris(mut self, tris: &'a [[u32; 3]]) -> Self {
        self.candidate_tris = Some(tris);
        self
    }

    /// Verifies also that every vertex's triangles from each side (`sides[t]` for candidate
    /// triangle `t`: the chunk it lies in) form one simple path or cycle, so that each chunk's
    /// part of the surface around a vertex shared by two chunks is one fan: clustering each
    /// chunk's inside afterwards, with the shared vertices kept, then keeps their links whole.
    pub(crate) fn with_sides(mut self, sides: &'a [u8]) -> Self {
        self.sides = Some(sides);
        self
    }

    /// Clusters whose members are pinned: `pin[v]` names the place (position, normal) of the
    /// cluster of `v` (all members of one cluster name the same), or is `NONE`. A pinned cluster
    /// was made and verified together with the neighbouring chunk (the face clusters of
    /// regularised tetrahedra): it goes where it is told, even with one member here, and is
    /// never taken apart; its standing vertex must be locked.
    pub(crate) fn with_pins(mut self, pin: &'a [u32], places: &'a [([f32; 3], [f32; 3])]) -> Self {
        self.pins = Some((pin, places));
        self
    }

    /// Places merged vertices on multiples of `step` (a power of two) along `axis` before they
    /// are verified: a chunk face's clusters, made in the upper chunk's frame, then move into the
    /// lower chunk's by adding the chunk's width without rounding, so both chunks hold the same
    /// vertex bit for bit.
    pub(crate) fn with_snap(mut self, axis: usize, step: f32) -> Self {
        self.snap = Some((axis, step));
        self
    }

    /// The place of the pinned cluster standing at `r`, if it is one.
    fn pinned(&self, r: usize) -> Option<(Vec3, Vec3)> {
        let (pin, places) = self.pins?;
        let i = pin[r];
        (i != NONE).then(|| (Vec3::from(places[i as usize].0), Vec3::from(places[i as usize].1)))
    }

    /// The candidate samples (position, normal) vertex `v` stands for.
    fn samples(&self, v: u32) -> impl Iterator<Item = (Vec3, Vec3)> + '_ {
        let (positions, normals, list): (&[[f32; 3]], &[[f32; 3]], &[u32]) = match self.hermite {
            Some((p, n, s)) => (p, n, s.of(v)),
            None => (self.positions, self.normals, std::slice::from_ref(&NO_LIST)),
        };
        let own = self.hermite.is_none().then_some(v);
        list.iter()
            .map(move |&c| own.unwrap_or(c))
            .map(move |c| (Vec3::from(positions[c as usize]), Vec3::from(normals[c as usize])))
    }

    pub(crate) fn new(
        positions: &'a [[f32; 3]],
        normals: &'a [[f32; 3]],
        tris: &'a [[u32; 3]],
        locked: &'a [bool],
        cell: f32,
    ) -> Self {
        Clustering {
            positions,
            normals,
            tris,
            locked,
            cell,
            max_rms: None,
            hermite: None,
            candidate_tris: None,
            reach: MAX_REACH_CELLS,
            off: MAX_MOVE_CELLS,
            sides: None,
            pins: None,
            snap: None,
        }
    }

    /// Clusters by `rep` (for each vertex, a vertex of its cluster that stands for it, the
    /// same for all members; locked vertices stand for themselves).
    pub(crate) fn run(&self, mut rep: Vec<u32>) -> Clustered {
        let n = self.positions.len();
        debug_assert_eq!(rep.len(), n);
        let mut pos: Vec<Vec3> = self.positions.iter().map(|&p| Vec3::from(p)).collect();
        let mut nrm: Vec<Vec3> = self.normals.iter().map(|&q| Vec3::from(q)).collect();
        let mut first = vec![NONE; n];
        let mut next = vec![NONE; n];
        let mut bad = vec![false; n];
        let mut mapped: Vec<[u32; 3]> = Vec::with_capacity(self.tris.len());
        let mut offsets: Vec<u32> = Vec::new();
        let mut link: Vec<(u32, u32)> = Vec::new();
        let mut folded: Vec<(u32, u32)> = Vec::new();
        let mut mapped_sides: Vec<u8> = Vec::new();
        // Whether a merged cluster has a candidate beyond [`MAX_REACH_CELLS`] of its vertex.
        let mut far = vec![false; n];
        // With the candidate triangles: the vertex of this mesh standing for each candidate.
        let mut owner: Vec<u32> = Vec::new();
        if let (Some(_), Some((positions, _, samples))) = (&self.candidate_tris, self.hermite) {
            owner.resize(positions.len(), NONE);
            for v in 0..n as u32 {
                for &c in samples.of(v) {
                    owner[c as usize] = v;
                }
            }
        }
        // Members of each cluster as linked lists (in vertex order).
        for v in (0..n).rev() {
            let r = rep[v] as usize;
            next[v] = first[r];
            first[r] = v as u32;
        }
        // Take apart the clusters whose members are not joined by the mesh's edges among
        // themselves: they would join separate pieces or sheets, or let a small piece vanish
        // into a cluster that also holds another surface.
        let mut root: Vec<u32> = (0..n as u32).collect();
        fn find(root: &mut [u32], mut v: u32) -> u32 {
            while root[v as usize] != v {
                root[v as usize] = root[root[v as usize] as usize];
                v = root[v as usize];
            }
            v
        }
        for tri in self.tris {
            for (a, b) in [(tri[0], tri[1]), (tri[1], tri[2]), (tri[2], tri[0])] {
                if rep[a as usize] == rep[b as usize] {
                    let (ra, rb) = (find(&mut root, a), find(&mut root, b));
                    root[ra.max(rb) as usize] = ra.min(rb);
                }
            }
        }
        for r in 0..n {
            if rep[r] as usize == r && merged(&first, &next, r as u32) && self.pinned(r).is_none() {
                let own = find(&mut root, r as u32);
                if self.members(r as u32, &first, &next).any(|m| find(&mut root, m) != own) {
                    self.split(r, &mut rep, &mut first, &mut next, &mut pos, &mut nrm);
                }
            }
        }
        // Place each cluster; take apart the ones whose members stray. Clusters taken apart
        // later go back to their members' positions; the others keep theirs.
        for r in 0..n {
            if rep[r] as usize != r {
                continue;
            }
            if let Some((p, q)) = self.pinned(r) {
                (pos[r], nrm[r]) = (p, q);
                continue;
            }
            if merged(&first, &next, r as u32) {
                match self.place(r as u32, &first, &next) {
                    Some((p, q, beyond)) => (pos[r], nrm[r], far[r]) = (p, q, beyond),
                    None => self.split(r, &mut rep, &mut first, &mut next, &mut pos, &mut nrm),
                }
            }
        }
        loop {
            // Carry the triangles through; mark clusters whose triangles turn over.
            mapped.clear();
            mapped_sides.clear();
            folded.clear();
            bad.fill(false);
            for (t, tri) in self.tris.iter().enumerate() {
                let m = tri.map(|v| rep[v as usize]);
                if m[0] == m[1] || m[1] == m[2] || m[0] == m[2] {
                    // A triangle folded onto an edge: that edge must stay in the surface.
                    if m[0] != m[1] || m[1] != m[2] {
                        let other = if m[0] == m[1] { m[2] } else { m[1] };
                        folded.push((m[0], other));
                    }
                    continue;
                }
                // A triangle moves when any corner's cluster has moved (its standing vertex is
                // a member too, so a triangle may keep its corners and still move).
                let moved = m.iter().any(|&r| merged(&first, &next, r));
                if moved && (self.turns_over(*tri, m, &pos) || self.cuts_away(m, &pos, &nrm)) {
                    for r in m {
                        bad[r as usize] = true;
                    }
                }
                mapped.push(m);
                if let Some(sides) = self.sides {
                    mapped_sides.push(sides[t]);
                }
            }
            self.check_links(&rep, &mapped, &mapped_sides, &mut offsets, &mut link, &mut bad);
            if self.hermite.is_some() {
                self.check_far_samples(&rep, &pos, (&first, &next), &far, &offsets, &link, &mut bad);
            }
            for &(a, b) in &folded {
                let around = &link[offsets[a as usize] as usize..offsets[a as usize + 1] as usize];
                if !around.iter().any(|&(u, w)| u == b || w == b) {
                    bad[a as usize] = true;
                    bad[b as usize] = true;
                }
            }
            let mut any = self.split_bad(&bad, &mut rep, &mut first, &mut next, &mut pos, &mut nrm);
            // Once the rest holds: the candidate triangles around far candidates (costlier,
            // so measured on a surface that passed everything else).
            if !any && self.candidate_tris.is_some() {
                bad.fill(false);
                self.check_far_triangles(&rep, &pos, (&first, &next), &owner, &offsets, &link, &mut bad);
                any = self.split_bad(&bad, &mut rep, &mut first, &mut next, &mut pos, &mut nrm);
            }
            if !any {
                break;
            }
        }
        self.output(&rep, &pos, (&first, &next), &far, &mapped)
    }

    /// Takes apart every merged, unpinned cluster whose standing vertex is marked `bad`;
    /// whether any was.
    fn split_bad(
        &self,
        bad: &[bool],
        rep: &mut [u32],
        first: &mut [u32],
        next: &mut [u32],
        pos: &mut [Vec3],
        nrm: &mut [Vec3],
    ) -> bool {
        let mut any = false;
        for r in 0..rep.len() {
            if bad[r] && rep[r] as usize == r && merged(first, next, r as u32) && self.pinned(r).is_none() {
                self.split(r, rep, first, next, pos, nrm);
                any = true;
            }
        }
        any
    }

    /// Makes every member of cluster `r` a cluster of its own, at its own position.
    fn split(
        &self,
        r: usize,
        rep: &mut [u32],
        first: &mut [u32],
        next: &mut [u32],
        pos: &mut [Vec3],
        nrm: &mut [Vec3],
    ) {
        let mut m = first[r];
        while m != NONE {
            let after = next[m as usize];
            rep[m as usize] = m;
            pos[m as usize] = Vec3::from(self.positions[m as usize]);
            nrm[m as usize] = Vec3::from(self.normals[m as usize]);
            first[m as usize] = m;
            next[m as usize] = NONE;
            m = after;
        }
    }

    fn members<'b>(&self, r: u32, first: &'b [u32], next: &'b [u32]) -> impl Iterator<Item = u32> + 'b {
        std::iter::successors(Some(first[r as usize]), |&m| Some(next[m as usize]).filter(|&n| n != NONE))
    }

    /// Where cluster `r` goes, its mean normal, and whether a member lies farther than
    /// [`MAX_REACH_CELLS`] from it. The place is the minimiser of the members' tangent planes
    /// (biased to their mean where the planes leave a direction free, kept within half a cell of
    /// the members' box), or where a member would stray from that, the point halfway to the
    /// members' mean, or the mean; `None` when members stray from all three (see the module's
    /// notes).
    fn place(&self, r: u32, first: &[u32], next: &[u32]) -> Option<(Vec3, Vec3, bool)> {
        let origin = Vec3::from(self.positions[r as usize]);
        let mut qef = Qef::default();
        let (mut lo, mut hi, mut normal) = (Vec3::splat(f32::MAX), Vec3::splat(f32::MIN), Vec3::ZERO);
        for m in self.members(r, first, next) {
            for (p, q) in self.samples(m) {
                qef.add((p - origin).as_dvec3(), q.as_dvec3());
                lo = lo.min(p);
                hi = hi.max(p);
                normal += q;
            }
        }
        let margin = Vec3::splat(0.5 * self.cell);
        let sharp = (origin + qef.solve().as_vec3()).clamp(lo - margin, hi + margin);
        let mean = origin + qef.mass_point().as_vec3();
        let normal = normal.normalize_or_zero();
        let (off, reach) = (self.off * self.cell, (self.reach * self.cell).powi(2));
        let near = (MAX_REACH_CELLS * self.cell).powi(2);
        let (mut nearest, mut farthest) = (f32::MAX, 0f32);
        let mut fits = |p: Vec3| {
            (nearest, farthest) = (f32::MAX, 0.0);
            let strays = self.members(r, first, next).flat_map(|m| self.samples(m)).any(|(q, qn)| {
                let d = q.distance_squared(p);
                (nearest, farthest) = (nearest.min(d), farthest.max(d));
                qn.dot(normal) <= 0.0 || normal.dot(q - p).abs() > off || d > reach
            });
            let rms = |max: f32| ((qef.error((p - origin).as_dvec3()) / qef.count() as f64).sqrt() as f32) <= max;
            !strays && nearest <= near && p.is_finite() && self.max_rms.is_none_or(rms)
        };
        // The planes' meeting point keeps a crease or a corner sharp; where it lies too far from
        // a member (a corner sharper than the candidates' chamfer by more than the reach), the
        // vertex goes halfway to the members' mean, then to the mean, chamfering as they do.
        let snap = |mut p: Vec3| {
            if let Some((axis, step)) = self.snap {
                p[axis] = (p[axis] / step).round() * step;
            }
            p
        };
        let p = [sharp, sharp.lerp(mean, 0.5), mean].into_iter().map(snap).find(|&p| fits(p))?;
        Some((p, normal, farthest > near))
    }

    /// Whether candidate triangle `tri`, carried to `m` (positions `pos`), turns over or loses
    /// its area. A candidate sliver with no reliable direction is judged by its corners' normals.
    fn turns_over(&self, tri: [u32; 3], m: [u32; 3], pos: &[Vec3]) -> bool {
        let old = tri.map(|v| Vec3::from(self.positions[v as usize]));
        let new = m.map(|v| pos[v as usize]);
        let scale = (old[1] - old[0]).length_squared().max((old[2] - old[0]).length_squared());
        let n0 = (old[1] - old[0]).cross(old[2] - old[0]);
        let reference = if n0.length_squared() > 1e-8 * scale * scale {
            n0
        } else {
            tri.iter().map(|&v| Vec3::from(self.normals[v as usize])).sum()
        };
        let n1 = (new[1] - new[0]).cross(new[2] - new[0]);
        let l1 = n1.length_squared();
        n1.dot(reference) <= 0.0 || l1 <= 1e-12 * (self.cell * self.cell).powi(2)
    }

    /// Whether triangle `m` (positions `pos`, vertex normals `nrm`) cuts away from the surface:
    /// its centroid or an edge midpoint lies farther than [`MAX_CHORD_CELLS`] from the tangent
    /// planes of all three corners (a chord across a tip or a groove narrower than a cell).
    fn cuts_away(&self, m: [u32; 3], pos: &[Vec3], nrm: &[Vec3]) -> bool {
        let p = m.map(|v| pos[v as usize]);
        let n = m.map(|v| nrm[v as usize]);
        let limit = MAX_CHORD_CELLS * self.cell;
        [(p[0] + p[1] + p[2]) / 3.0, (p[0] + p[1]) * 0.5, (p[1] + p[2]) * 0.5, (p[2] + p[0]) * 0.5]
            .into_iter()
            .any(|x| (0..3).all(|k| n[k].dot(x - p[k]).abs() > limit))
    }

    /// For a mesh clustered again (whose clusters may reach farther than [`MAX_REACH_CELLS`]
    /// from their candidates): marks the clusters around every vertex with a candidate farther
    /// than that from the vertex and from every triangle around it (a tip or a fin cut short).
    /// Only vertices that moved, or whose neighbours did, are looked at: the others kept their
    /// triangles, which passed this check when they were made.
    #[allow(clippy::too_many_arguments)]
    fn check_far_samples(
        &self,
        rep: &[u32],
        pos: &[Vec3],
        (first, next): (&[u32], &[u32]),
        far: &[bool],
        offsets: &[u32],
        link: &[(u32, u32)],
        bad: &mut [bool],
    ) {
        let near = MAX_REACH_CELLS * self.cell;
        for r in 0..rep.len() {
            if rep[r] as usize != r || !self.is_far(r as u32, first, next, far) {
                continue;
            }
            let fan = &link[offsets[r] as usize..offsets[r + 1] as usize];
            if !near_a_merge(r, fan, first, next) {
                continue;
            }
            let p = pos[r];
            let strays = |q: Vec3| strays(q, p, fan, pos, near);
            let cut = self.members(r as u32, first, next).flat_map(|m| self.samples(m)).any(|(q, _)| strays(q));
            if cut {
                mark_around(bad, r, fan);
            }
        }
    }

    /// For a mesh clustered again, with the candidate triangles: marks the clusters around a
    /// vertex where a candidate triangle with a corner farther than [`MAX_REACH_CELLS`] from its
    /// vertex has an edge midpoint or its centroid farther than that from the vertex and from
    /// every triangle around it. A sample's image (the same mean of its corners' vertices) lies
    /// on the clustered surface no farther from it than the mean of its corners' moves, so only
    /// where that mean passes the bound is the sample measured. Only vertices that moved, or
    /// whose neighbours did, are looked at, as in [`Clustering::check_far_samples`].
    #[allow(clippy::too_many_arguments)]
    fn check_far_triangles(
        &self,
        rep: &[u32],
        pos: &[Vec3],
        (first, next): (&[u32], &[u32]),
        owner: &[u32],
        offsets: &[u32],
        link: &[(u32, u32)],
        bad: &mut [bool],
    ) {
        let (Some(tris), Some((positions, _, _))) = (self.candidate_tris, self.hermite) else { return };
        let near = MAX_REACH_CELLS * self.cell;
        let vertex = |c: u32| rep[owner[c as usize] as usize];
        // How far each candidate lies from its vertex.
        let moves: Vec<f32> = (0..positions.len() as u32)
            .map(|c| {
                if owner[c as usize] == NONE {
                    0.0
                } else {
                    Vec3::from(positions[c as usize]).distance(pos[vertex(c) as usize])
                }
            })
            .collect();
        for tri in tris {
            let m = tri.map(|c| moves[c as usize]);
            if m.iter().all(|&d| d <= near) {
                continue;
            }
            let q = tri.map(|c| Vec3::from(positions[c as usize]));
            for k in 0..3 {
                if m[k] <= near {
                    continue;
                }
                let r = vertex(tri[k]) as usize;
                let fan = &link[offsets[r] as usize..offsets[r + 1] as usize];
                if !near_a_merge(r, fan, first, next) {
                    continue;
                }
                let j = (k + 1) % 3;
                // Each edge from the far corner once (the one leaving it); the centroid.
                let cut = ((m[k] + m[j]) * 0.5 > near && strays((q[k] + q[j]) * 0.5, pos[r], fan, pos, near))
                    || ((m[0] + m[1] + m[2]) / 3.0 > near
                        && strays((q[0] + q[1] + q[2]) / 3.0, pos[r], fan, pos, near));
                if cut {
                    mark_around(bad, r, fan);
                }
            }
        }
    }

    /// Whether cluster `r` has a candidate farther than [`MAX_REACH_CELLS`] from its vertex
    /// (`far`: the merged clusters'; a vertex standing alone is as it came).
    fn is_far(&self, r: u32, first: &[u32], next: &[u32], far: &[bool]) -> bool {
        if merged(first, next, r) { far[r as usize] } else { self.hermite.is_some_and(|(_, _, s)| s.far[r as usize]) }
    }

    /// Marks, for every vertex whose link is not one simple cycle (a simple path or cycle for a
    /// vertex that stays), or with sides, whose link's part from one side is not one simple path
    /// or cycle, the clusters of the vertex and of every vertex beside it.
    fn check_links(
        &self,
        rep: &[u32],
        mapped: &[[u32; 3]],
        mapped_sides: &[u8],
        offsets: &mut Vec<u32>,
        link: &mut Vec<(u32, u32)>,
        bad: &mut [bool],
    ) {
        let n = self.positions.len();
        offsets.clear();
        offsets.resize(n + 1, 0);
        for m in mapped {
            for &v in m {
                offsets[v as usize + 1] += 1;
            }
        }
        for i in 0..n {
            offsets[i + 1] += offsets[i];
        }
        link.clear();
        link.resize(mapped.len() * 3, (NONE, NONE));
        // With sides: the side of each link edge's triangle.
        let mut link_sides = vec![0u8; if mapped_sides.is_empty() { 0 } else { mapped.len() * 3 }];
        let mut fill: Vec<u32> = offsets[..n].to_vec();
        for (t, m) in mapped.iter().enumerate() {
            for k in 0..3 {
                let v = m[k] as usize;
                link[fill[v] as usize] = (m[(k + 1) % 3], m[(k + 2) % 3]);
                if let Some(side) = mapped_sides.get(t) {
                    link_sides[fill[v] as usize] = *side;
                }
                fill[v] += 1;
            }
        }
        let mut part: SmallVec<[(u32, u32); 16]> = SmallVec::new();
        let mut marks: Vec<u32> = Vec::new();
        let mut vanished: Vec<u32> = Vec::new();
        for v in 0..n {
            let edges = &link[offsets[v] as usize..offsets[v + 1] as usize];
            if edges.is_empty() {
                // A candidate vertex whose cluster lost every triangle: a small closed piece
                // fell into fewer than three clusters and vanished.
                let r = rep[v] as usize;
                if offsets[r] == offsets[r + 1] {
                    vanished.push(r as u32);
                }
                continue;
            }
            let sided =
                &link_sides[if link_sides.is_empty() { 0..0 } else { offsets[v] as usize..offsets[v + 1] as usize }];
            let sides_whole = sided.iter().all(|&s| s == sided[0])
                || [0u8, 1].into_iter().all(|side| {
                    part.clear();
                    part.extend(edges.iter().zip(sided).filter(|e| *e.1 == side).map(|e| *e.0));
                    part.is_empty() || link_is_disk(&part, true)
                });
            if sides_whole && link_is_disk(edges, self.locked[v]) {
                continue;
            }
            marks.push(v as u32);
            marks.extend(edges.iter().flat_map(|&(a, b)| [a, b]));
        }
        for v in marks {
            bad[v as usize] = true;
        }
        if !vanished.is_empty() {
            // Take apart every cluster of the candidate triangles the vanished ones held.
            let mut gone = vec![false; n];
            for r in vanished {
                gone[r as usize] = true;
            }
            for tri in self.tris {
                if tri.iter().any(|&v| gone[rep[v as usize] as usize]) {
                    for v in tri {
                        bad[rep[*v as usize] as usize] = true;
                    }
                }
            }
        }
    }

    fn output(
        &self,
        rep: &[u32],
        pos: &[Vec3],
        (first, next): (&[u32], &[u32]),
        far: &[bool],
        mapped: &[[u32; 3]],
    ) -> Clustered {
        let n = self.positions.len();
        let mut index = vec![NONE; n];
        for m in mapped {
            for &v in m {
                index[v as usize] = 0;
            }
        }
        let mut out = Clustered {
            positions: Vec::new(),
            normals: Vec::new(),
            tris: Vec::new(),
            kept: Vec::new(),
            samples: Samples { start: vec![0], list: Vec::new(), far: Vec::new() },
        };
        for r in 0..n {
            if index[r] == NONE {
                continue;
            }
            debug_assert_eq!(rep[r] as usize, r);
            index[r] = out.positions.len() as u32;
            let mut normal = Vec3::ZERO;
            for m in self.members(r as u32, first, next) {
                normal += self.samples(m).map(|(_, q)| q).sum::<Vec3>();
                match self.hermite {
                    Some((_, _, s)) => out.samples.list.extend_from_slice(s.of(m)),
                    None => out.samples.list.push(m),
                }
            }
            out.samples.start.push(out.samples.list.len() as u32);
            out.samples.far.push(self.is_far(r as u32, first, next, far));
            out.positions.push(pos[r].to_array());
            let normal = self.pinned(r).map_or(normal, |(_, q)| q);
            out.normals.push(normal.normalize_or(Vec3::from(self.normals[r])).to_array());
            out.kept.push(r as u32);
        }
        out.tris = mapped.iter().map(|m| m.map(|v| index[v as usize])).collect();
        out
    }
}

/// Whether vertex `r` or one beside it (`fan`: the directed edges opposite it) moved: merged
/// in this clustering (its cluster's member lists `first` and `next`).
fn near_a_merge(r: usize, fan: &[(u32, u32)], first: &[u32], next: &[u32]) -> bool {
    merged(first, next, r as u32) || fan.iter().any(|&(u, w)| merged(first, next, u) || merged(first, next, w))
}

/// Marks vertex `r` and the vertices around it (`fan`) `bad`.
fn mark_around(bad: &mut [bool], r: usize, fan: &[(u32, u32)]) {
    bad[r] = true;
    for &(u, w) in fan {
        bad[u as usize] = true;
        bad[w as usize] = true;
    }
}

/// Whether `q` lies farther than `near` from vertex `p` and from every triangle around it
/// (`fan`: the directed edges opposite `p`, positions `pos`). A corner of a triangle within
/// `near` settles it without the full distance.
fn strays(q: Vec3, p: Vec3, fan: &[(u32, u32)], pos: &[Vec3], near: f32) -> bool {
    q.distance_squared(p) > near * near
        && fan.iter().all(|&(u, w)| {
            let (b, c) = (pos[u as usize], pos[w as usize]);
            q.distance_squared(b) > near * near
                && q.distance_squared(c) > near * near
                && crate::checks::point_triangle_distance(q.as_dvec3(), p.as_dvec3(), b.as_dvec3(), c.as_dvec3())
                    > near as f64
        })
}

/// Whether the cluster standing at `r` (its member lists `first` and `next`) has more than one
/// member, so that its vertex moved.
fn merged(first: &[u32], next: &[u32], r: u32) -> bool {
    next[first[r as usize] as usize] != NONE
}

/// The edges of `mesh` shorter than `max_len` between vertices that may move, matched greedily
/// shortest first (each vertex in one pair at most): a clustering for [`Clustering::run`].
pub(crate) fn short_pairs(mesh: &Clustered, locked: &[bool], max_len: f32) -> Vec<u32> {
    let n = mesh.positions.len();
    let mut edges: Vec<(u32, u32, u32)> = Vec::new();
    for t in &mesh.tris {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            // Each edge once (its other triangle runs it the other way).
            if a < b && !locked[a as usize] && !locked[b as usize] {
                let l = Vec3::from(mesh.positions[a as usize]).distance(Vec3::from(mesh.positions[b as usize]));
                if l < max_len {
                    edges.push((l.to_bits(), a, b));
                }
            }
        }
    }
    edges.sort_unstable();
    let mut rep: Vec<u32> = (0..n as u32).collect();
    let mut taken = vec![false; n];
    for (_, a, b) in edges {
        if !taken[a as usize] && !taken[b as usize] {
            taken[a as usize] = true;
            taken[b as usize] = true;
            rep[b as usize] = a;
        }
    }
    rep
}

/// Whether the directed edges opposite a vertex (one per triangle around it) form one simple
/// cycle of at least three edges, or with `open`, one simple path or cycle.
fn link_is_disk(edges: &[(u32, u32)], open: bool) -> bool {
    let k = edges.len();
    if k < 3 && !open {
        return false;
    }
    // Every start and every end once.
    for i in 0..k {
        for j in i + 1..k {
            if edges[i].0 == edges[j].0 || edges[i].1 == edges[j].1 {
                return false;
            }
        }
    }
    let follows = |v: u32| edges.iter().position(|e| e.0 == v);
    // A path starts at the one start that is no end; a cycle anywhere.
    let starts: SmallVec<[usize; 2]> = (0..k).filter(|&i| !edges.iter().any(|e| e.1 == edges[i].0)).collect();
    let (start, cycle) = match starts.len() {
        0 => (0, true),
        1 if open => (starts[0], false),
        _ => return false,
    };
    let mut steps = 1;
    let mut at = edges[start].1;
    while let Some(i) = follows(at) {
        if cycle && i == start {
            break;
        }
        steps += 1;
        if steps > k {
            return false;
        }
        at = edges[i].1;
    }
    steps == k
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A regular octahedron (±x, ±y, ±z) with outward triangles, and the vertex normals `normals`.
    type Candidates = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[u32; 3]>);

    fn octahedron(normals: [[f32; 3]; 6]) -> Candidates {
        let positions = vec![
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
        ];
        let tris = vec![[0, 2, 4], [2, 1, 4], [1, 3, 4], [3, 0, 4], [2, 0, 5], [1, 2, 5], [3, 1, 5], [0, 3, 5]];
        (positions, normals.to_vec(), tris)
    }

    fn outward() -> [[f32; 3]; 6] {
        [[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0], [0.0, 0.0, -1.0]]
    }

    #[test]
    fn a_safe_cluster_merges_and_the_surface_stays_closed() {
        let (p, n, t) = octahedron(outward());
        let locked = [false; 6];
        // +x and +y into one vertex: their two shared triangles fall away, a bipyramid is left.
        let c = Clustering::new(&p, &n, &t, &locked, 10.0).run(vec![0, 1, 0, 3, 4, 5]);
        assert_eq!((c.positions.len(), c.tris.len()), (5, 6));
        assert_eq!(c.kept, vec![0, 1, 3, 4, 5]);
        // The planes x = 1 and y = 1 meet at (1, 1, 0).
        assert!(Vec3::from(c.positions[0]).distance(Vec3::new(1.0, 1.0, 0.0)) < 1e-4, "{:?}", c.positions[0]);
    }

    #[test]
    fn with_sides_each_sides_triangles_around_a_vertex_form_one_fan() {
        let (p, n, t) = octahedron(outward());
        let locked = [false; 6];
        let run =
            |sides: &[u8]| Clustering::new(&p, &n, &t, &locked, 10.0).with_sides(sides).run(vec![0, 1, 0, 3, 4, 5]);
        // {+x, +y} merged: its four triangles, two from each side, side by side: kept.
        let c = run(&[0, 1, 0, 1, 0, 0, 0, 0]);
        assert_eq!((c.positions.len(), c.tris.len()), (5, 6));
        // The same cluster where each side's two triangles lie opposite each other (the surface
        // would pass from one chunk to the other and back around the vertex): taken apart,
        // though the whole link is one cycle.
        let c = run(&[0, 1, 0, 0, 0, 0, 0, 1]);
        assert_eq!((c.positions.len(), c.tris.len()), (6, 8));
    }

    #[test]
    fn a_pinned_cluster_goes_where_it_is_told_and_stays() {
        // +x and +y pinned to (1, 1, 0.5) with its own normal, though their planes meet at
        // (1, 1, 0); +x stands for it and is locked, as a chunk's pinned face cluster is.
        let (p, n, t) = octahedron(outward());
        let mut locked = [false; 6];
        locked[0] = true;
        let pin = [0, NONE, 0, NONE, NONE, NONE];
        let places = [([1.0, 1.0, 0.5], [0.0, 0.0, 1.0])];
        let c = Clustering::new(&p, &n, &t, &locked, 10.0).with_pins(&pin, &places).run(vec![0, 1, 0, 3, 4, 5]);
        assert_eq!((c.positions.len(), c.tris.len()), (5, 6));
        assert_eq!((c.positions[0], c.normals[0]), places[0]);
        // Even where its members would fail the checks here (planes that turn a triangle over):
        // it was verified with the members this chunk does not see.
        let mut normals = outward();
        let k = 13f32.sqrt();
        normals[0] = [2.0 / k, -3.0 / k, 0.0];
        normals[2] = [3.0 / k, -2.0 / k, 0.0];
        let (p, n, t) = octahedron(normals);
        let c = Clustering::new(&p, &n, &t, &locked, 10.0).with_pins(&pin, &places).run(vec![0, 1, 0, 3, 4, 5]);
        assert_eq!(c.positions.len(), 5);
    }

    #[test]
    fn a_corner_beyond_the_reach_is_chamfered_instead() {
        let (p, n, t) = octahedron(outward());
        let locked = [false; 6];
        // The cluster {+x, +y} as its member lists.
        let mut first = vec![NONE; 6];
        let mut next = vec![NONE; 6];
        (first[0], next[0]) = (0, 2);
        let at = |cell: f32| Clustering::new(&p, &n, &t, &locked, cell).place(0, &first, &next).map(|(v, ..)| v);
        // Cells of 10: the planes x = 1 and y = 1 meet at (1, 1, 0), within the reach.
        assert!(at(10.0).unwrap().distance(Vec3::new(1.0, 1.0, 0.0)) < 1e-4);
        // Cells of 1.9 (reach 0.95): (1, 1, 0) lies 1 from both members, so the vertex goes
        // halfway to their mean (0.5, 0.5, 0).
        assert!(at(1.9).unwrap().distance(Vec3::new(0.75, 0.75, 0.0)) < 1e-4);
        // Cells of 1.2 (reach 0.6): not even the mean (0.71 from both) lies within the reach.
        assert_eq!(at(1.2), None);
    }

    #[test]
    fn a_cluster_whose_vertex_turns_a_triangle_over_is_taken_apart() {
        // Tangent planes at +x and +y that meet at (-2, -2, 0), beyond -x and -y: the merged
        // vertex passes every distance bound of a cell of 10 but turns its neighbours over.
        let mut normals = outward();
        let k = 13f32.sqrt();
        normals[0] = [2.0 / k, -3.0 / k, 0.0];
        normals[2] = [3.0 / k, -2.0 / k, 0.0];
        let (p, n, t) = octahedron(normals);
        let c = Clustering::new(&p, &n, &t, &[false; 6], 10.0).run(vec![0, 1, 0, 3, 4, 5]);
        assert_eq!((c.positions.len(), c.tris.len()), (6, 8), "taken apart: the octahedron unchanged");
        assert_eq!(c.positions, p);
    }

    #[test]
    fn a_triangle_that_keeps_its_corners_but_moves_is_checked_too() {
        // +x stands for the cluster {+x, +y}; planes meeting at (-1, 0.6, 0) turn over only the
        // triangles around +x that +y is not in (their corners do not change, their position
        // does).
        let mut normals = outward();
        let (a, b) = (Vec3::new(0.6, 2.0, 0.0).normalize(), Vec3::new(0.4, -1.0, 0.0).normalize());
        normals[0] = a.to_array();
        normals[2] = b.to_array();
        let (p, n, t) = octahedron(normals);
        let c = Clustering::new(&p, &n, &t, &[false; 6], 10.0).run(vec![0, 1, 0, 3, 4, 5]);
        assert_eq!((c.positions.len(), c.tris.len()), (6, 8), "taken apart");
    }

    #[test]
    fn a_cluster_that_pinches_or_flattens_the_surface_is_taken_apart() {
        // Normals that let the members merge (so only the surface's shape can refuse).
        let (p, n, t) = octahedron([[0.0, 0.0, 1.0]; 6]);
        // +x with -x: opposite vertices; the triangles around the merged vertex touch in two
        // fans (a pinch). +x, -x, +y: three of four around the equator leave triangles back
        // to back.
        for rep in [vec![0, 0, 2, 3, 4, 5], vec![0, 0, 0, 3, 4, 5]] {
            let c = Clustering::new(&p, &n, &t, &[false; 6], 10.0).run(rep.clone());
            assert_eq!(c.tris.len(), 8, "{rep:?}");
        }
        // Everything into one vertex: the piece would vanish.
        let c = Clustering::new(&p, &n, &t, &[false; 6], 10.0).run(vec![0; 6]);
        assert_eq!(c.tris.len(), 8);
    }

    #[test]
    fn a_cluster_joining_two_separate_pieces_is_taken_apart() {
        // A speck (a tiny octahedron) at the big octahedron's +x corner, all of it clustered
        // with that corner: its triangles would all fall away while the corner keeps its own
        // link, so only the members' connectedness can refuse.
        let (mut p, mut n, mut t) = octahedron(outward());
        let (q, _, u) = octahedron(outward());
        p.extend(q.iter().map(|v| [1.0 + 0.01 * v[0], 0.01 * v[1], 0.01 * v[2]]));
        n.extend([[1.0, 0.0, 0.0]; 6]);
        t.extend(u.iter().map(|f| f.map(|v| v + 6)));
        let mut rep: Vec<u32> = (0..12).collect();
        rep[6..].fill(0);
        let c = Clustering::new(&p, &n, &t, &[false; 12], 10.0).run(rep);
        assert_eq!((c.positions.len(), c.tris.len()), (12, 16), "the speck is kept");
    }

    #[test]
    fn a_triangle_cutting_across_a_ridge_cuts_away_and_one_along_a_plane_does_not() {
        let none: [[f32; 3]; 0] = [];
        let c = Clustering::new(&none, &none, &[], &[], 1.0);
        // A tent z = -|x|: corners on both faces and on the ridge, with their faces' normals.
        let k = std::f32::consts::FRAC_1_SQRT_2;
        let pos = [Vec3::new(-1.0, 0.0, -1.0), Vec3::new(1.0, 0.0, -1.0), Vec3::new(0.0, 1.0, 0.0)];
        let nrm = [Vec3::new(-k, 0.0, k), Vec3::new(k, 0.0, k), Vec3::Z];
        assert!(c.cuts_away([0, 1, 2], &pos, &nrm));
        // The same corners on a flat floor, and a shallow tent (its chord within 0.3 cells).
        let flat = [Vec3::Z; 3];
        let low = [Vec3::new(-1.0, 0.0, -0.2), Vec3::new(1.0, 0.0, -0.2), Vec3::new(0.0, 1.0, 0.0)];
        assert!(!c.cuts_away([0, 1, 2], &low.map(|p| p * Vec3::new(1.0, 1.0, 0.0)), &flat));
        let n = Vec3::new(-0.2, 0.0, 1.0).normalize();
        assert!(!c.cuts_away([0, 1, 2], &low, &[n, n * Vec3::new(-1.0, 1.0, 1.0), Vec3::Z]));
    }

    #[test]
    fn links_are_disks_only_when_one_simple_cycle() {
        assert!(link_is_disk(&[(1, 2), (2, 3), (3, 1)], false));
        assert!(link_is_disk(&[(2, 3), (4, 1), (1, 2), (3, 4)], false));
        // Two cycles (a pinch), a repeated start, too short, an open path.
        assert!(!link_is_disk(&[(1, 2), (2, 3), (3, 1), (4, 5), (5, 6), (6, 4)], false));
        assert!(!link_is_disk(&[(1, 2), (1, 3), (3, 1)], false));
        assert!(!link_is_disk(&[(1, 2), (2, 1)], false));
        assert!(!link_is_disk(&[(1, 2), (2, 3)], false));
        // Open (a vertex that stays): one path or one cycle, not two paths.
        assert!(link_is_disk(&[(1, 2), (2, 3)], true));
        assert!(link_is_disk(&[(7, 8)], true));
        assert!(link_is_disk(&[(1, 2), (2, 3), (3, 1)], true));
        assert!(!link_is_disk(&[(1, 2), (3, 4)], true));
        assert!(!link_is_disk(&[(1, 2), (2, 3), (3, 1), (5, 6)], true));
    }
}
