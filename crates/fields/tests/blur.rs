//! The dense baseline's box-blur smoothing (godot_voxel's smooth tool), checked.

use glam::{DVec3, I64Vec3};
use strata_fields::{DenseField, FieldError};
use strata_volume::CsgOp;
use strata_volume::brush::Sphere;

#[test]
fn the_box_blur_lowers_a_bump_and_leaves_the_rest() {
    let mut f = DenseField::new();
    f.apply(CsgOp::Add, &Sphere::new(DVec3::splat(24.0), 12.0).unwrap()).unwrap();
    f.apply(CsgOp::Add, &Sphere::new(DVec3::new(36.0, 24.0, 24.0), 2.0).unwrap()).unwrap();
    let far = I64Vec3::new(12, 24, 24);
    let before_far = f.value(far);
    let tip = |f: &DenseField| {
        (0..1000).map(|i| 40.0 - i as f64 * 0.01).find(|&x| f.sample(DVec3::new(x, 24.0, 24.0)) <= 0.0)
    };
    let t0 = tip(&f).unwrap();
    for _ in 0..6 {
        let changed = f.smooth_box_blur(DVec3::new(36.0, 24.0, 24.0), 5.0, 1.0).unwrap();
        assert!(!changed.is_empty());
    }
    let t1 = tip(&f).unwrap();
    assert!(t1 < t0 - 0.5, "the bump's tip went from {t0} to {t1}");
    assert_eq!(f.value(far), before_far, "outside the ball nothing changes");
}

#[test]
fn bad_smoothing_dabs_are_refused() {
    let mut f = DenseField::new();
    for (c, r, s) in [
        (DVec3::NAN, 2.0, 1.0),
        (DVec3::ZERO, 0.0, 1.0),
        (DVec3::ZERO, f64::INFINITY, 1.0),
        (DVec3::ZERO, 2.0, 1.5),
        (DVec3::ZERO, 2.0, f32::NAN),
    ] {
        assert_eq!(f.smooth_box_blur(c, r, s), Err(FieldError::BadDab));
    }
    assert!(matches!(f.smooth_box_blur(DVec3::ZERO, 1e5, 1.0), Err(FieldError::TooLarge { .. })));
    assert_eq!(f.chunk_count(), 0);
    // Smoothing empty space changes nothing and allocates nothing.
    assert!(f.smooth_box_blur(DVec3::splat(5.0), 3.0, 1.0).unwrap().is_empty());
    assert_eq!(f.chunk_count(), 0);
}
