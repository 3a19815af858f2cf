//! Row-major image buffers: what the image files hold (a PFM is a [`FloatImage`]) and what
//! the estimator works on, owned by the caller and reused frame after frame. `reset`
//! keeps the allocation when the size does not grow, which is how the estimator's
//! per-frame path stays free of allocation. [`ImageView`] borrows someone else's pixels
//! (a camera driver's buffer, a numpy array) with any row stride, so a frame reaches the
//! estimator without a copy.

use crate::Error;

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

/// A borrowed row-major image of `T`: `height` rows of `width` pixels, each row
/// `stride_bytes` after the one before (rows may be padded, or a crop of a larger image).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ImageView<'a, T> {
    width: usize,
    height: usize,
    /// Row to row, in elements of `T`.
    stride: usize,
    data: &'a [T],
}

impl<'a, T: Copy> ImageView<'a, T> {
    /// A view of `data` as `width` x `height` pixels with rows `stride_bytes` apart. Refused
    /// when the stride is shorter than a row or not a whole number of pixels, or `data`
    /// ends before the last row does.
    pub fn new(data: &'a [T], width: usize, height: usize, stride_bytes: usize) -> Result<Self, Error> {
        let size = std::mem::size_of::<T>().max(1);
        if !stride_bytes.is_multiple_of(size) || stride_bytes / size < width {
            return Err(Error::value(
                "stride",
                format!(
                    "{stride_bytes} bytes, expected a whole number of pixels, at least one row ({} bytes)",
                    width * size
                ),
            ));
        }
        let stride = stride_bytes / size;
        let needed = if height == 0 || width == 0 { 0 } else { (height - 1) * stride + width };
        if data.len() < needed {
            return Err(Error::value(
                "data",
                format!("{} pixels, expected at least {needed} for {width} x {height} with a stride of {stride_bytes} bytes", data.len()),
            ));
        }
        Ok(ImageView { width, height, stride, data })
    }

    /// The view of a whole owned image (rows back to back).
    pub fn of(image: &'a Image<T>) -> Self {
        ImageView { width: image.width, height: image.height, stride: image.width, data: &image.data }
    }

    /// Pixels per row.
    pub fn width(&self) -> usize {
        self.width
    }

    /// Rows.
    pub fn height(&self) -> usize {
        self.height
    }

    /// From one row's start to the next, bytes.
    pub fn stride_bytes(&self) -> usize {
        self.stride * std::mem::size_of::<T>()
    }

    /// From one row's start to the next, pixels.
    pub fn stride(&self) -> usize {
        self.stride
    }

    /// The borrowed pixels, from the first row's start (padding between rows included).
    pub fn data(&self) -> &'a [T] {
        self.data
    }

    /// Whether rows follow each other without padding, so `data()` is the image row-major.
    pub fn is_contiguous(&self) -> bool {
        self.stride == self.width || self.height <= 1
    }

    /// Row `y`.
    #[inline]
    pub fn row(&self, y: usize) -> &'a [T] {
        &self.data[y * self.stride..y * self.stride + self.width]
    }

    /// Pixel at column `x`, row `y`.
    #[inline]
    pub fn get(&self, x: usize, y: usize) -> T {
        self.data[y * self.stride + x]
    }

    /// An owned copy, rows back to back.
    pub fn to_image(&self) -> Image<T> {
        let mut data = Vec::with_capacity(self.width * self.height);
        for y in 0..self.height {
            data.extend_from_slice(self.row(y));
        }
        Image { width: self.width, height: self.height, data }
    }
}

/// What can be seen as an [`ImageView`]: an owned image or a view itself, so a frame's
/// shots may be passed as either without building a list of views.
pub trait AsImageView<T> {
    /// The whole image as a view.
    fn as_view(&self) -> ImageView<'_, T>;
}

impl<T: Copy> AsImageView<T> for Image<T> {
    fn as_view(&self) -> ImageView<'_, T> {
        ImageView::of(self)
    }
}

impl<T: Copy> AsImageView<T> for ImageView<'_, T> {
    fn as_view(&self) -> ImageView<'_, T> {
        *self
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_padded_view_reads_the_pixels_of_its_rows_only() {
        // 3 x 2 pixels in rows of 5 bytes; the padding holds 99.
        let data = [1u8, 2, 3, 99, 99, 4, 5, 6];
        let v = ImageView::new(&data, 3, 2, 5).unwrap();
        assert!(!v.is_contiguous());
        assert_eq!((v.row(0), v.row(1), v.get(2, 1)), (&[1u8, 2, 3][..], &[4u8, 5, 6][..], 6));
        assert_eq!(v.to_image(), Image::from_vec(3, 2, vec![1, 2, 3, 4, 5, 6]).unwrap());
        let owned = v.to_image();
        assert_eq!(owned.as_view().to_image(), owned);
        assert!(owned.as_view().is_contiguous());
    }

    #[test]
    fn a_view_past_its_data_or_with_a_short_stride_is_refused() {
        let data = [0u8; 8];
        assert!(ImageView::new(&data, 3, 2, 2).unwrap_err().to_string().contains("stride"));
        assert!(ImageView::new(&data, 3, 2, 6).unwrap_err().to_string().contains("expected at least 9"));
        let wide = [0u16; 4];
        assert!(ImageView::new(&wide, 2, 2, 3).is_err());
        assert_eq!(ImageView::new(&wide, 2, 2, 4).unwrap().stride(), 2);
    }
}
