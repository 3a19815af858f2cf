//! camplace's benches, one module per topic, in a single criterion binary.

mod features;
mod hand_eye;
mod phase;
mod pipeline;
mod pose;
mod render;
mod slots;
mod stereo;

criterion::criterion_group!(phase_benches, phase::benches);
criterion::criterion_group!(feature_benches, features::benches);
criterion::criterion_group!(pipeline_benches, pipeline::benches);
criterion::criterion_main!(
    render::benches,
    stereo::benches,
    phase_benches,
    feature_benches,
    pose::benches,
    slots::benches,
    pipeline_benches,
    hand_eye::benches
);
