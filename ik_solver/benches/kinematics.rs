//! Cost of the per-tick kinematics of the default robot: one leg's closed-form IK, both legs
//! into a joint vector, and forward kinematics of every link followed by the whole-body CoM.
//!
//! cargo bench -p ik_solver --bench kinematics -- --warm-up-time 1 --measurement-time 3
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::hint::black_box;

use criterion::{Criterion, criterion_group, criterion_main};
use ik_solver::{AnkleTarget, BipedModel, DEFAULT_URDF, Side};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};

fn biped() -> BipedModel {
    match BipedModel::from_urdf_str(DEFAULT_URDF, None) {
        Ok(b) => b,
        Err(e) => panic!("default robot does not load: {e}"),
    }
}

/// Mid-step targets of a walk: the body 2 cm low, the swing foot ahead, the stance foot behind,
/// both slightly inward. Reachable and within limits, so the benches time the exact path.
fn walking_targets() -> (AnkleTarget, AnkleTarget) {
    (
        AnkleTarget::new(0.025, -0.004, -0.155),
        AnkleTarget::new(-0.02, 0.006, -0.16),
    )
}

fn ik(c: &mut Criterion) {
    let b = biped();
    let (left, right) = walking_targets();
    let sol = b.solve_leg(Side::Left, &left).ok();
    assert!(
        sol.as_ref().is_some_and(|s| s.is_exact()),
        "benchmark target is not solved exactly: {sol:?}"
    );
    let mut q = vec![0.0; b.robot().dof_count()];
    let issues = b.solve_legs(&left, &right, &mut q).ok();
    assert!(
        issues.as_ref().is_some_and(Vec::is_empty),
        "benchmark targets are not solved exactly: {issues:?}"
    );

    let mut g = c.benchmark_group("ik");
    g.bench_function("one_leg", |bench| {
        bench.iter(|| b.solve_leg(black_box(Side::Left), black_box(&left)))
    });
    g.bench_function("both_legs", |bench| {
        bench.iter(|| {
            let issues = b.solve_legs(black_box(&left), black_box(&right), black_box(&mut q));
            black_box(&q);
            issues
        })
    });
    g.finish();
}

fn fk(c: &mut Criterion) {
    let b = biped();
    let robot = b.robot();
    let (left, right) = walking_targets();
    let mut q = vec![0.0; robot.dof_count()];
    // Legs from IK, arms and head somewhere off zero.
    for (i, v) in q.iter_mut().enumerate() {
        *v = 0.05 * (i % 5) as f64 - 0.1;
    }
    let issues = b.solve_legs(&left, &right, &mut q).ok();
    assert!(issues.is_some_and(|i| i.is_empty()));
    let base = Isometry3::from_parts(
        Translation3::new(0.1, 0.02, 0.24),
        UnitQuaternion::from_euler_angles(0.02, 0.05, 0.3),
    );
    let mut poses = Vec::with_capacity(robot.links().len());

    let mut g = c.benchmark_group("fk");
    g.bench_function("link_poses_into+com", |bench| {
        bench.iter(|| {
            let ok = robot.link_poses_into(black_box(&base), black_box(&q), &mut poses);
            (ok, robot.center_of_mass(black_box(&poses)))
        })
    });
    g.finish();
}

/// The six inverse tangents of a both-leg solve: the C library's one by one against the
/// branch-free batch the IK uses.
fn trig(c: &mut Criterion) {
    let y: [f64; 6] = [0.31, -0.02, 0.5, 1e-3, 0.8, -0.27];
    let x: [f64; 6] = [0.9, 0.04, -0.12, 0.2, 0.79, -0.3];
    let mut g = c.benchmark_group("trig");
    g.bench_function("atan2_x6/libm", |bench| {
        bench.iter(|| {
            let (y, x) = (black_box(y), black_box(x));
            std::array::from_fn::<f64, 6, _>(|i| y[i].atan2(x[i]))
        })
    });
    g.bench_function("atan2_x6/batch", |bench| {
        bench.iter(|| ik_solver::trig::atan2_each(black_box(y), black_box(x)))
    });
    g.finish();
}

criterion_group!(benches, ik, fk, trig);
criterion_main!(benches);
