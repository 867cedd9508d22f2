//! The field operators on the region primitive: inflate, smooth (all three methods) and
//! flatten, measured; and stamps, placed and turned.

use glam::DVec3;
use strata_volume::brush::{Cuboid, Sphere};
use strata_volume::tools::{
    BuiltinStamp, Dab, Falloff, FalloffCurve, Smoothing, StampImage, StampPlacement, ToolError, falloff, flatten,
    inflate, smooth, stamp,
};
use strata_volume::{Axis, Volume};

struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// `count` directions spread evenly over the sphere (a Fibonacci lattice).
fn directions(count: usize) -> Vec<DVec3> {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    (0..count)
        .map(|i| {
            let z = 1.0 - 2.0 * (i as f64 + 0.5) / count as f64;
            let r = (1.0 - z * z).sqrt();
            let a = golden * i as f64;
            DVec3::new(r * a.cos(), r * a.sin(), z)
        })
        .collect()
}

/// The surface's distance from `c` along `dir`, by a ray cast from outside.
fn radius_along(v: &Volume, c: DVec3, dir: DVec3) -> f64 {
    let far = 80.0;
    let hit = v.raycast(c + dir * far, -dir, 2.0 * far).expect("the ray meets the solid");
    far - hit.t
}

/// RMS deviation of the radii from their mean, over `dirs`.
fn radial_rms(v: &Volume, c: DVec3, dirs: &[DVec3]) -> (f64, f64) {
    let r: Vec<f64> = dirs.iter().map(|&d| radius_along(v, c, d)).collect();
    let mean = r.iter().sum::<f64>() / r.len() as f64;
    ((r.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / r.len() as f64).sqrt(), mean)
}

#[test]
fn inflate_moves_the_surface_by_the_amount_at_the_dab_centre() {
    let c = DVec3::new(30.0, 30.5, 29.75);
    for amount in [2.0, -2.0] {
        let mut v = Volume::new();
        v.add(&Sphere::new(c, 15.0).unwrap()).unwrap();
        let before = radius_along(&v, c, DVec3::X);
        let dab = Dab::new(c + DVec3::X * 15.0, 8.0, 1.0).unwrap();
        let report = inflate(&mut v, &dab, amount).unwrap();
        v.check_invariants().unwrap();
        let grown = radius_along(&v, c, DVec3::X) - before;
        assert!((grown - amount).abs() <= 0.1 * amount.abs(), "asked for {amount}, moved {grown}");
        // Outside the dab nothing moved.
        assert!((radius_along(&v, c, -DVec3::X) - 15.0).abs() < 0.05);
        let mut undone = v.clone();
        undone.restore(report.undo);
        let mut fresh = Volume::new();
        fresh.add(&Sphere::new(c, 15.0).unwrap()).unwrap();
        assert_eq!(undone, fresh);
    }
}

/// A sphere of radius 20 roughened by 200 small spheres added and subtracted on its surface.
fn rough_sphere(c: DVec3) -> Volume {
    let mut v = Volume::new();
    v.add(&Sphere::new(c, 20.0).unwrap()).unwrap();
    let mut rng = Rng(5);
    for (i, d) in directions(200).into_iter().enumerate() {
        let r = 1.5 + rng.unit() * 1.5;
        let b = Sphere::new(c + d * 20.0, r).unwrap();
        if i % 2 == 0 {
            v.add(&b).unwrap();
        } else {
            v.subtract(&b).unwrap();
        }
    }
    v
}

/// Smoothing dabs over the whole sphere of radius `r` about `c`.
fn smooth_all(v: &mut Volume, c: DVec3, r: f64, method: Smoothing, passes: u32) {
    for d in directions(60) {
        let dab = Dab::new(c + d * r, 9.0, 1.0).unwrap();
        smooth(v, &dab, method, passes).unwrap();
        v.check_invariants().unwrap();
    }
}

#[test]
fn smoothing_a_rough_sphere_cuts_its_roughness_and_keeps_its_volume() {
    let c = DVec3::new(32.0, 32.0, 32.0);
    let dirs = directions(400);
    for (method, max_volume_change) in
        [(Smoothing::Laplacian, 0.10), (Smoothing::VolumePreserving, 0.02), (Smoothing::Endpoints, 0.10)]
    {
        let mut v = rough_sphere(c);
        let (rough, _) = radial_rms(&v, c, &dirs);
        let vol = v.measured_volume(Axis::X);
        smooth_all(&mut v, c, 20.0, method, 12);
        let (smooth_rms, _) = radial_rms(&v, c, &dirs);
        let change = (v.measured_volume(Axis::X) / vol - 1.0).abs();
        eprintln!("{method:?}: RMS {rough:.3} -> {smooth_rms:.3} cells, volume changed {:.2} %", change * 100.0);
        assert!(smooth_rms <= 0.4 * rough, "{method:?}: RMS {rough} -> {smooth_rms} (at least 60 % less)");
        assert!(change <= max_volume_change, "{method:?}: volume changed {:.2} %", change * 100.0);
    }
}

#[test]
fn smoothing_leaves_a_plane_and_a_large_sphere_in_place() {
    // A flat floor whose top is at z = 16.3.
    let mut v = Volume::new();
    v.add(&Cuboid::new(DVec3::new(24.0, 24.0, 8.3), DVec3::new(30.0, 30.0, 8.0)).unwrap()).unwrap();
    let top = |v: &Volume| 40.0 - v.raycast(DVec3::new(24.3, 23.8, 40.0), -DVec3::Z, 60.0).unwrap().t;
    let before = top(&v);
    for _ in 0..5 {
        let dab = Dab::new(DVec3::new(24.3, 23.8, 16.3), 8.0, 1.0).unwrap();
        smooth(&mut v, &dab, Smoothing::VolumePreserving, 4).unwrap();
        smooth(&mut v, &dab, Smoothing::Laplacian, 4).unwrap();
        smooth(&mut v, &dab, Smoothing::Endpoints, 4).unwrap();
    }
    v.check_invariants().unwrap();
    assert!((top(&v) - before).abs() < 0.1, "the plane moved {}", top(&v) - before);
    // A sphere of radius 30, ten passes over its surface, volume-preserving.
    let c = DVec3::new(40.0, 40.0, 40.0);
    let mut s = Volume::new();
    s.add(&Sphere::new(c, 30.0).unwrap()).unwrap();
    let dirs = directions(200);
    let (_, r0) = radial_rms(&s, c, &dirs);
    smooth_all(&mut s, c, 30.0, Smoothing::VolumePreserving, 10);
    let (_, r1) = radial_rms(&s, c, &dirs);
    assert!((r1 - r0).abs() < 0.25, "the radius-30 sphere's radius moved {} cells", r1 - r0);
}

#[test]
fn flatten_takes_the_bumps_out_of_a_plane() {
    let mut v = Volume::new();
    v.add(&Cuboid::new(DVec3::new(24.0, 24.0, 8.0), DVec3::new(30.0, 30.0, 8.0)).unwrap()).unwrap();
    let mut rng = Rng(11);
    for _ in 0..30 {
        let p = DVec3::new(16.0 + rng.unit() * 16.0, 16.0 + rng.unit() * 16.0, 16.0);
        let b = Sphere::new(p, 1.0 + rng.unit() * 1.5).unwrap();
        if rng.unit() < 0.5 {
            v.add(&b).unwrap();
        } else {
            v.subtract(&b).unwrap();
        }
    }
    // RMS deviation of the heights over the middle of the patch from their mean (the
    // horizontal plane that fits them best).
    let rms = |v: &Volume| {
        let mut h = Vec::new();
        for i in 0..12 {
            for j in 0..12 {
                let (x, y) = (19.25 + i as f64 * 0.8, 19.1 + j as f64 * 0.8);
                h.push(40.0 - v.raycast(DVec3::new(x, y, 40.0), -DVec3::Z, 60.0).unwrap().t);
            }
        }
        let mean = h.iter().sum::<f64>() / h.len() as f64;
        (h.iter().map(|z| (z - mean).powi(2)).sum::<f64>() / h.len() as f64).sqrt()
    };
    let before = rms(&v);
    // The documented use: four dabs at the patch's centre.
    for _ in 0..4 {
        flatten(&mut v, &Dab::new(DVec3::new(24.0, 24.0, 16.0), 10.0, 1.0).unwrap()).unwrap();
    }
    v.check_invariants().unwrap();
    let after = rms(&v);
    eprintln!("flatten: RMS {before:.3} -> {after:.3}");
    assert!(after <= 0.2 * before, "RMS {before} -> {after} (at least 80 % less)");
}

#[test]
fn bad_dabs_are_errors_not_panics() {
    assert!(matches!(Dab::new(DVec3::NAN, 1.0, 1.0), Err(ToolError::BadParameter { .. })));
    for r in [0.0, -1.0, f64::NAN, f64::INFINITY] {
        assert!(Dab::new(DVec3::ZERO, r, 1.0).is_err(), "radius {r}");
    }
    for s in [-0.1, 1.5, f64::NAN] {
        assert!(Dab::new(DVec3::ZERO, 1.0, s).is_err(), "strength {s}");
    }
    let mut v = Volume::new();
    v.add(&Sphere::new(DVec3::splat(8.0), 5.0).unwrap()).unwrap();
    let before = v.clone();
    let dab = Dab::new(DVec3::splat(8.0), 3.0, 1.0).unwrap();
    assert!(inflate(&mut v, &dab, f64::INFINITY).is_err());
    assert!(inflate(&mut v, &dab, f64::NAN).is_err());
    let huge = Dab::new(DVec3::ZERO, 1e6, 1.0).unwrap();
    assert!(matches!(smooth(&mut v, &huge, Smoothing::Laplacian, 1), Err(ToolError::Region(_))));
    assert_eq!(v, before, "refused dabs change nothing");
    // A dab over empty space changes nothing.
    let empty = Dab::new(DVec3::splat(200.0), 4.0, 1.0).unwrap();
    assert!(flatten(&mut v, &empty).unwrap().changed.is_empty());
    assert!(smooth(&mut v, &empty, Smoothing::VolumePreserving, 3).unwrap().changed.is_empty());
}

#[test]
fn laplacian_smoothing_shrinks_a_sphere_as_mean_curvature_flow() {
    // On a distance field, `φ += w Δφ / 6` per pass is a step dt = w / 6 of mean-curvature flow:
    // a sphere's radius follows dr/dt = −2 / r, r² = r₀² − 4t. A dab centred on the sphere, of
    // radius R, weighs every surface point alike, w = falloff(r / R), so
    // d(r²)/dt = −4 falloff(r / R); the region is read again at every dab (four passes).
    let c = DVec3::new(40.2, 39.9, 40.1);
    let r0 = 12.0;
    let big = 40.0;
    let mut v = Volume::new();
    v.add(&Sphere::new(c, r0).unwrap()).unwrap();
    let dirs = directions(64);
    let (_, measured0) = radial_rms(&v, c, &dirs);
    let dabs = 8;
    let passes = 4;
    for _ in 0..dabs {
        smooth(&mut v, &Dab::new(c, big, 1.0).unwrap(), Smoothing::Laplacian, passes).unwrap();
    }
    v.check_invariants().unwrap();
    let (_, measured) = radial_rms(&v, c, &dirs);
    // The predicted radius: r² integrated in small steps of t.
    let t_total = (dabs * passes) as f64 / 6.0;
    let mut r2 = measured0 * measured0;
    let steps = 1000;
    for _ in 0..steps {
        r2 -= 4.0 * falloff(r2.sqrt() / big) * t_total / steps as f64;
    }
    let (drop, predicted) = (measured0 * measured0 - measured * measured, measured0 * measured0 - r2);
    eprintln!("r² fell by {drop:.2}, mean-curvature flow predicts {predicted:.2} (r {measured0:.3} -> {measured:.3})");
    assert!((drop - predicted).abs() <= 0.05 * predicted, "r² fell by {drop}, predicted {predicted}");
}

/// A slab whose top face lies on the grid plane z = 16 (every node of the face on it), and the
/// height of its top at `(x, y)`.
fn slab() -> Volume {
    let mut v = Volume::new();
    v.add(&Cuboid::new(DVec3::new(24.0, 24.0, 8.0), DVec3::new(30.0, 30.0, 8.0)).unwrap()).unwrap();
    v
}

fn top(v: &Volume, x: f64, y: f64) -> f64 {
    40.0 - v.raycast(DVec3::new(x, y, 40.0), -DVec3::Z, 60.0).unwrap().t
}

#[test]
fn a_stamp_raises_its_picture_and_carves_it_with_a_negative_height() {
    let c = DVec3::new(24.0, 24.0, 16.0);
    let ring = BuiltinStamp::Ring.image();
    let placement = StampPlacement::default();
    for height in [2.0, -2.0] {
        let mut v = slab();
        let fresh = v.clone();
        let dab = Dab::new(c, 10.0, 1.0).unwrap();
        let report = stamp(&mut v, &dab, &ring, &placement, height).unwrap();
        v.check_invariants().unwrap();
        // The ring (at 0.55 of the radius) moves by the height; its middle and the slab
        // beyond the radius stay.
        for a in 0..8 {
            let (s, k) = (a as f64 * std::f64::consts::TAU / 8.0).sin_cos();
            let moved = top(&v, 24.0 + 5.5 * k, 24.0 + 5.5 * s) - 16.0;
            assert!((moved - height).abs() < 0.25, "height {height}: the ring moved {moved}");
        }
        assert!((top(&v, 24.0, 24.0) - 16.0).abs() < 0.1, "the ring's middle stays");
        // (A face on a grid plane is stored a hair off it.)
        assert_eq!(top(&v, 35.0, 24.0), top(&fresh, 35.0, 24.0), "beyond the radius nothing moves");
        v.restore(report.undo);
        assert_eq!(v, fresh, "a stamp undoes exactly");
    }
}

#[test]
fn a_stamp_turns_with_its_up_direction_and_angle_and_mirrors() {
    // An image white in its top-right quarter only.
    let side = 32;
    let corner = StampImage::from_fn(side, |u, v| if u > 0.15 && v > 0.15 { 1.0 } else { 0.0 });
    let c = DVec3::new(24.0, 24.0, 16.0);
    let raised = |placement: StampPlacement| {
        let mut v = slab();
        stamp(&mut v, &Dab::new(c, 10.0, 1.0).unwrap(), &corner, &placement, 2.0).unwrap();
        v.check_invariants().unwrap();
        // Which quarter rose (seen from above, +z out of the slab: x right, y up).
        let mut q = Vec::new();
        for (sx, sy) in [(1.0, 1.0), (-1.0, 1.0), (-1.0, -1.0), (1.0, -1.0)] {
            q.push(top(&v, 24.0 + 4.0 * sx, 24.0 + 4.0 * sy) - 16.0 > 1.0);
        }
        q
    };
    let up = StampPlacement { up: DVec3::Y, angle: 0.0, mirrored: false };
    assert_eq!(raised(up), [true, false, false, false], "up +y: the top-right quarter");
    let quarter = StampPlacement { angle: std::f64::consts::FRAC_PI_2, ..up };
    assert_eq!(raised(quarter), [false, true, false, false], "a quarter turn counter-clockwise");
    let left = StampPlacement { up: -DVec3::X, ..up };
    assert_eq!(raised(left), [false, true, false, false], "up along −x is the same turn");
    let mirrored = StampPlacement { mirrored: true, ..up };
    assert_eq!(raised(mirrored), [false, true, false, false], "mirrored: left for right");
}

#[test]
fn a_stamp_over_empty_space_or_with_bad_numbers_changes_nothing() {
    let mut v = slab();
    let before = v.clone();
    let dome = BuiltinStamp::Dome.image();
    let dab = Dab::new(DVec3::new(24.0, 24.0, 16.0), 6.0, 1.0).unwrap();
    for (placement, height) in [
        (StampPlacement::default(), f64::NAN),
        (StampPlacement::default(), f64::INFINITY),
        (StampPlacement { angle: f64::NAN, ..Default::default() }, 1.0),
        (StampPlacement { up: DVec3::INFINITY, ..Default::default() }, 1.0),
    ] {
        assert!(matches!(stamp(&mut v, &dab, &dome, &placement, height), Err(ToolError::BadParameter { .. })));
    }
    let far = Dab::new(DVec3::splat(300.0), 6.0, 1.0).unwrap();
    assert!(stamp(&mut v, &far, &dome, &StampPlacement::default(), 2.0).unwrap().changed.is_empty());
    let huge = Dab::new(DVec3::ZERO, 1e6, 1.0).unwrap();
    assert!(matches!(stamp(&mut v, &huge, &dome, &StampPlacement::default(), 2.0), Err(ToolError::Region(_))));
    assert_eq!(v, before);
}

#[test]
fn the_falloff_shapes_an_inflate_across_its_radius() {
    let c = DVec3::new(24.0, 24.0, 16.0);
    let curve = FalloffCurve::new(&[(0.0, 0.0), (0.5, 1.0), (1.0, 0.0)]).unwrap();
    for falloff in [Falloff::Smooth, Falloff::Constant, Falloff::Linear, Falloff::Curve(curve)] {
        let mut v = slab();
        let fresh = v.clone();
        let dab = Dab { falloff, ..Dab::new(c, 10.0, 1.0).unwrap() };
        inflate(&mut v, &dab, 2.0).unwrap();
        v.check_invariants().unwrap();
        // The surface rose by the amount times the falloff at the risen point's distance from
        // the centre (the dab is a ball: `h = 2 f(√((10 t)² + h²) / 10)`, solved by iteration).
        for t in [0.1, 0.3, 0.5, 0.7] {
            let moved = top(&v, 24.0 + 10.0 * t, 24.0) - top(&fresh, 24.0 + 10.0 * t, 24.0);
            let mut want = 2.0 * falloff.at(t);
            for _ in 0..100 {
                want = 2.0 * falloff.at(((10.0 * t).powi(2) + want * want).sqrt() / 10.0);
            }
            assert!((moved - want).abs() < 0.12, "{} at {t}: moved {moved}, want {want}", falloff.name());
        }
    }
}
