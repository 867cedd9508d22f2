//! The memory figures of the three representations equal what a counting global allocator
//! sees them hold. One test in this binary, so no other test allocates meanwhile.

use stats_alloc::{INSTRUMENTED_SYSTEM, Region, StatsAlloc};
use std::alloc::System;
use strata_bench::baselines::{replay_dense, replay_narrow};
use strata_bench::{replay, table1_instructions};

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

/// Bytes allocated and not yet freed since `region` began.
fn live(region: &Region<'_, System>) -> isize {
    let c = region.change();
    c.bytes_allocated as isize - c.bytes_deallocated as isize
}

#[test]
fn memory_reports_equal_the_bytes_the_allocator_holds() {
    let ins = table1_instructions(150, 9.0, 5);
    // A first replay, not measured: whatever the edit path creates once per process (thread
    // pools, their threads' own buffers) is made now, not inside a region. Without it a CI run
    // counted 900 bytes more than the volume holds, once in many runs.
    drop(replay(&ins, false));

    let region = Region::new(GLOBAL);
    // The replay's scratch buffers are freed when it returns; the volume is what stays.
    let volume = replay(&ins, false).volume;
    let held = live(&region);
    let reported = volume.memory().total() as isize;
    assert!(reported > 100_000, "the workload builds something ({reported} bytes)");
    assert_eq!(held, reported, "segment volume: allocator {held} B, report {reported} B");
    drop(volume);

    let region = Region::new(GLOBAL);
    let (r, dense) = replay_dense(&ins);
    let (held, reported) = (live(&region), dense.memory() as isize);
    assert_eq!(reported, r.final_memory as isize);
    assert_eq!(held, reported, "dense field: allocator {held} B, report {reported} B");
    drop(dense);

    let region = Region::new(GLOBAL);
    let (_, narrow) = replay_narrow(&ins, 2.0);
    let held = live(&region);
    // The field keeps one decoding buffer (27 chunks of scratch) besides its data.
    let scratch = (27 * 4096 * 4) as isize;
    let reported = narrow.memory() as isize;
    assert_eq!(held - scratch, reported, "narrow band: allocator {held} B (incl. scratch), report {reported} B");
}
