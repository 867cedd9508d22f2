//! Workloads shared by the benches and the bench binary.
