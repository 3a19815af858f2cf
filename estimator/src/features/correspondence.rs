//! A feature correspondence: a scene key point matched to a model feature.

/// One match of a scene key point to a model feature, with its squared descriptor distance.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Correspondence {
    /// Index of the scene key point.
    pub scene: u32,
    /// Index of the model feature.
    pub model: u32,
    /// Squared L2 distance between the two descriptors.
    pub distance2: f32,
}
