//! camplace's benches, one criterion binary with a module per topic (`cargo bench --bench
//! lib -- <topic>`), each on seeded or deterministic inputs.

use criterion::{criterion_group, criterion_main};

mod features;

criterion_group!(benches, features::benches);
criterion_main!(benches);
