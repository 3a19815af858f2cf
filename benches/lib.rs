//! The criterion benches: one module per topic, one binary.

use criterion::{criterion_group, criterion_main};

mod phase;

criterion_group!(benches, phase::benches);
criterion_main!(benches);
