//! camplace's benches, one module per topic, in a single criterion binary.

mod phase;
mod pose;
mod render;
mod stereo;

criterion::criterion_group!(phase_benches, phase::benches);
criterion::criterion_main!(render::benches, stereo::benches, phase_benches, pose::benches);
