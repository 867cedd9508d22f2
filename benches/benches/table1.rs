//! Criterion bench of the paper's Table 1 workload on the segment volume: per radius, the
//! replay of 1000 random sphere draw/erase instructions on a 160³ canvas. Reported time is per
//! instruction (throughput elements = instructions); `edit` is Time_d, `extract` Time_v.

use std::time::Duration;

use criterion::{BenchmarkId, Criterion, Throughput, criterion_group, criterion_main};
use strata_bench::{replay, table1_instructions};

fn table1(c: &mut Criterion) {
    for (part, parallel) in [("single_thread", false), ("rayon", true)] {
        let mut group = c.benchmark_group(format!("table1_canvas160_1000_spheres/{part}"));
        group.sample_size(10).measurement_time(Duration::from_secs(20));
        for radius in [5.0, 10.0, 15.0, 20.0, 40.0] {
            let ins = table1_instructions(1000, radius, 2021);
            group.throughput(Throughput::Elements(ins.len() as u64));
            group.bench_with_input(BenchmarkId::new("edit", radius), &ins, |b, ins| {
                b.iter_custom(|iters| (0..iters).map(|_| replay(ins, parallel).edit).sum())
            });
            group.bench_with_input(BenchmarkId::new("extract", radius), &ins, |b, ins| {
                b.iter_custom(|iters| (0..iters).map(|_| replay(ins, parallel).extract).sum())
            });
        }
        group.finish();
    }
}

criterion_group!(benches, table1);
criterion_main!(benches);
