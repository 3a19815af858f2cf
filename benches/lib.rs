//! camplace's benches: one criterion binary, a module per topic.

mod pose;

criterion::criterion_main!(pose::benches);
