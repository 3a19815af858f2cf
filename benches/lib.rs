//! camplace's benches, one module per topic, in a single criterion binary.

mod render;

criterion::criterion_main!(render::benches);
