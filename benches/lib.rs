//! camplace's benches, one module per topic, in a single criterion binary.

mod stereo;

criterion::criterion_main!(stereo::benches);
