//! Row-major image buffers: what the image files hold (a PFM is a [`FloatImage`]) and what
//! the estimator works on, owned by the caller and reused frame after frame. `reset`
//! keeps the allocation when the size does not grow, which is how the estimator's
//! per-frame path stays free of allocation.

/// A row-major image of `T`, origin top-left.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Image<T> {
    pub width: usize,
    pub height: usize,
    pub data: Vec<T>,
}

/// 8-bit grey image.
pub type GrayImage = Image<u8>;
/// 32-bit float image (disparity, depth, phase).
pub type FloatImage = Image<f32>;

impl<T: Copy> Image<T> {
    /// An image of `width` x `height` filled with `value`.
    pub fn new(width: usize, height: usize, value: T) -> Self {
        Image { width, height, data: vec![value; width * height] }
    }

    /// Wraps row-major pixels; `None` when the length is not `width * height`.
    pub fn from_vec(width: usize, height: usize, data: Vec<T>) -> Option<Self> {
        (data.len() == width * height).then_some(Image { width, height, data })
    }

    /// Sets the size and fills with `value`, reusing the allocation when it is big enough.
    pub fn reset(&mut self, width: usize, height: usize, value: T) {
        self.width = width;
        self.height = height;
        self.data.clear();
        self.data.resize(width * height, value);
    }

    /// Pixel at column `x`, row `y`.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> T {
        self.data[y * self.width + x]
    }

    /// Sets the pixel at column `x`, row `y`.
    #[inline]
    pub fn set(&mut self, x: usize, y: usize, v: T) {
        self.data[y * self.width + x] = v;
    }

    /// Row `y`.
    #[inline]
    pub fn row(&self, y: usize) -> &[T] {
        &self.data[y * self.width..(y + 1) * self.width]
    }

    /// Row `y`, mutable.
    #[inline]
    pub fn row_mut(&mut self, y: usize) -> &mut [T] {
        &mut self.data[y * self.width..(y + 1) * self.width]
    }

    /// Whether both images have the same size.
    pub fn same_size<U>(&self, other: &Image<U>) -> bool {
        self.width == other.width && self.height == other.height
    }
}
