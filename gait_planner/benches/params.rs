//! What giving the planner parameters costs between walks, as the node does at every walk
//! command: the parameters it holds again, and parameters it has not been checked for (one
//! millimetre more foot lift: every check walk again, and with durations left at 0 the
//! timing search too, which the node runs on another thread).
//!
//! cargo bench -p gait_planner --bench params -- --warm-up-time 1 --measurement-time 5
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::hint::black_box;

use criterion::{BatchSize, Criterion, criterion_group, criterion_main};
use gait_planner::{GaitParams, GaitPlanner};
use ik_solver::{BipedModel, DEFAULT_URDF};

fn model() -> BipedModel {
    match BipedModel::from_urdf_str(DEFAULT_URDF, None) {
        Ok(b) => b,
        Err(e) => panic!("default robot does not load: {e}"),
    }
}

fn set_params(c: &mut Criterion) {
    let model = model();
    // The default parameters (durations auto: the timing search is kept with the planner)
    // and the slow walk's (every duration set).
    for (name, params) in [
        ("default", GaitParams::default()),
        ("slow", GaitParams::slow(&model)),
    ] {
        let planner = GaitPlanner::new(model.clone(), params.clone()).unwrap();
        let mut other = params.clone();
        other.foot_lift_m += 0.001;
        let mut g = c.benchmark_group(format!("set_params_{name}"));
        g.sample_size(10);
        g.bench_function("same", |b| {
            b.iter_batched_ref(
                || planner.clone(),
                |p| p.set_params(black_box(params.clone())).unwrap(),
                BatchSize::SmallInput,
            )
        });
        g.bench_function("one_changed", |b| {
            b.iter_batched_ref(
                || planner.clone(),
                |p| p.set_params(black_box(other.clone())).unwrap(),
                BatchSize::SmallInput,
            )
        });
        g.finish();
    }
}

criterion_group!(benches, set_params);
criterion_main!(benches);
