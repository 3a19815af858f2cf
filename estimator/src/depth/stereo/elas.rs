//! The one-shot matcher after Geiger, Roser and Urtasun (2010), "Efficient Large-Scale
//! Stereo Matching": Sobel descriptors, robust support points, a Delaunay plane prior and
//! candidate grid, dense matching of both images near the prior, a left-right check, then
//! speckle removal, sub-pixel refinement and small-gap interpolation. Dense matching and
//! everything after it run on every `row_step`-th row only; the rows between are left
//! invalid in the map.
//!
//! Allocation: every buffer is sized in [`Elas::new`]; `compute` reuses them and never
//! allocates (the triangulation is structured by the support grid, see `triangulation`).

use camplace_config::StereoParams;
use rayon::prelude::*;

use super::cost::{DisparityRange, Kernel};
use super::dense::{match_row, Search, Side, VectorPrior, INVALID};
use super::descriptor::{column_weights, DescriptorImage, SobelPlanes, BORDER};
use super::postprocess::{interpolate_gaps, remove_speckles, SpeckleScratch};
use super::subpixel::{refine_subpixel, WORDS_PER_PIXEL};
use super::support::{SupportGrid, SupportParams, SupportPoint};
use super::triangulation::{CandidateGrid, Prior};
use super::DisparityMatcher;
use crate::depth::PixelRegion;
use crate::error::{Error, ErrorKind, Result};
use crate::{FloatImage, GrayImage};

/// The ELAS matcher with all its buffers.
#[derive(Clone, Debug)]
pub struct Elas {
    width: usize,
    height: usize,
    max_span: usize,
    support_uniqueness: f32,
    min_texture: i32,
    lr_tolerance: f32,
    prior_radius: i32,
    speckle_size: usize,
    speckle_similarity: f32,
    gap_width: usize,
    subpixel_radius: usize,
    /// Dense matching runs on every `row_step`-th row from row 0 (see
    /// `StereoParams::row_step`).
    row_step: usize,
    /// Prior energy by |d - prior| in px: -ln(gamma + exp(-delta^2 / 2 sigma^2)) + ln gamma,
    /// over beta, rounded (ELAS's Gaussian-plus-uniform prior).
    prior_energy: Vec<i32>,
    /// The same energies as the vector kernel reads them, when it can.
    vector_prior: VectorPrior,
    /// The fastest kernel this machine runs.
    kernel: Kernel,
    desc_left: DescriptorImage,
    desc_right: DescriptorImage,
    /// Working memory no step keeps past its own: the planes both images' descriptors are
    /// sampled from (one image after the other), then the sub-pixel refinement's.
    scratch: Vec<f32>,
    /// The descriptors' normalisation weights per column.
    column_weights: Vec<f32>,
    support: SupportGrid,
    points: Vec<SupportPoint>,
    prior: Prior,
    grid_left: CandidateGrid,
    grid_right: CandidateGrid,
    /// The left and the right image's maps on the matched rows only, row j holding image
    /// row j x `row_step` (every row at a row step of 1).
    dense_left: Vec<f32>,
    dense_right: Vec<f32>,
    speckles: SpeckleScratch,
}

impl Elas {
    /// A matcher for `width` x `height` rectified pairs whose search ranges span at most
    /// `max_disparity_span` px; allocates every buffer it will use.
    pub fn new(params: &StereoParams, width: usize, height: usize, max_disparity_span: usize) -> Elas {
        let step = params.support_step.max(1) as usize;
        let support = SupportGrid::new(width, height, step);
        let max_points = support.cols * support.rows + 4;
        let (gamma, sigma, beta) = (params.prior_gamma, params.prior_sigma, params.prior_beta);
        let prior_energy = (0..=max_disparity_span + 1)
            .map(|delta| {
                let delta = delta as f64;
                let p = -(gamma + (-delta * delta / (2.0 * sigma * sigma)).exp()).ln() + gamma.ln();
                (p / beta).round() as i32
            })
            .collect::<Vec<i32>>();
        let vector_prior = VectorPrior::new(&prior_energy, max_disparity_span + 1);
        let cell = params.grid_size.max(1) as usize;
        let row_step = params.row_step.max(1) as usize;
        let matched = width * height.div_ceil(row_step);
        Elas {
            width,
            height,
            max_span: max_disparity_span,
            support_uniqueness: params.support_uniqueness as f32,
            min_texture: params.min_texture as i32,
            lr_tolerance: params.lr_tolerance as f32,
            prior_radius: params.prior_radius as i32,
            speckle_size: params.speckle_size as usize,
            speckle_similarity: params.speckle_similarity as f32,
            gap_width: params.gap_width as usize,
            subpixel_radius: params.subpixel_radius as usize,
            row_step,
            prior_energy,
            vector_prior,
            kernel: Kernel::detect(),
            desc_left: DescriptorImage::new(width, height),
            desc_right: DescriptorImage::new(width, height),
            scratch: vec![0.0; (WORDS_PER_PIXEL * width * height).max(SobelPlanes::words_for(width, height))],
            column_weights: column_weights(width),
            support,
            points: Vec::with_capacity(max_points),
            prior: Prior::new(width, height, step, row_step),
            grid_left: CandidateGrid::new(width, height, cell, max_disparity_span),
            grid_right: CandidateGrid::new(width, height, cell, max_disparity_span),
            dense_left: vec![INVALID; matched],
            dense_right: vec![INVALID; matched],
            speckles: SpeckleScratch::new(width, height.div_ceil(row_step)),
        }
    }

    /// The support points of the last `compute` (left pixels, integer disparities).
    pub fn support_points(&self) -> &[SupportPoint] {
        &self.points
    }

    /// Matches with `kernel` instead of the fastest one (tests compare them).
    #[cfg(test)]
    pub(super) fn set_kernel(&mut self, kernel: Kernel) {
        self.kernel = kernel;
    }
}

impl DisparityMatcher for Elas {
    /// Searches from 0 when `range` starts below it. Images too small for a descriptor
    /// window (2 BORDER + 1 = 11 px across and down), down to none at all, are not an
    /// error: no pixel matches, so the map is all +inf.
    fn compute(&mut self, left: &GrayImage, right: &GrayImage, range: (f32, f32), out: &mut FloatImage) -> Result<()> {
        self.compute_in(left, right, range, PixelRegion::whole(self.width, self.height), out)
    }
}

impl Elas {
    /// [`DisparityMatcher::compute`] on the left pixels of `region` only (where the tray can
    /// be, see [`crate::depth::Foreground`]): support points and dense matching there, the
    /// right image's columns those pixels can match; every other pixel of the map is +inf.
    pub fn compute_in(
        &mut self,
        left: &GrayImage,
        right: &GrayImage,
        range: (f32, f32),
        region: PixelRegion,
        out: &mut FloatImage,
    ) -> Result<()> {
        let (w, h) = (self.width, self.height);
        if left.width != w
            || left.height != h
            || !left.same_size(right)
            || left.data.len() != w * h
            || right.data.len() != w * h
        {
            return Err(Error::new(
                ErrorKind::Input,
                format!(
                    "stereo pair: expected two {w}x{h} images, got {}x{} and {}x{}",
                    left.width, left.height, right.width, right.height
                ),
            ));
        }
        if !(range.0.is_finite() && range.1.is_finite() && range.0 <= range.1) {
            return Err(Error::new(ErrorKind::Input, format!("disparity range: expected min <= max, got {range:?}")));
        }
        // Disparities below 0 cannot occur on a rectified pair: the search starts at 0.
        let d_min = range.0.floor().max(0.0) as i32;
        let d_max = range.1.ceil().max(0.0) as i32;
        if (d_max - d_min) as usize > self.max_span {
            return Err(Error::new(
                ErrorKind::Input,
                format!("disparity range: spans {} px, the matcher was built for {} px", d_max - d_min, self.max_span),
            ));
        }
        let disparities = DisparityRange::new(d_min, d_max).ok_or_else(|| {
            Error::new(ErrorKind::Input, format!("disparity range: cannot search {d_min} to {d_max}"))
        })?;
        out.reset(w, h, INVALID);
        // An image without pixels has nothing to match: its map is empty.
        if w == 0 || h == 0 {
            return Ok(());
        }

        let kernel = self.kernel;
        let sp = SupportParams {
            range: disparities,
            uniqueness: self.support_uniqueness,
            min_texture: self.min_texture,
            lr_tolerance: self.lr_tolerance.round().max(1.0) as i32,
            kernel,
        };
        // Descriptors are read on the support grid's rows and the matched rows only.
        let (step, support_step) = (self.row_step, self.support.step);
        let rows = region.y0..region.y1.min(h);
        let wanted = |y: usize| y.is_multiple_of(step) || y.is_multiple_of(support_step);
        let mut planes = SobelPlanes::in_words(&mut self.scratch, &self.column_weights, w, h);
        self.desc_left.compute_rows(left, (rows.start, rows.end), &mut planes, wanted);
        self.desc_right.compute_rows(right, (rows.start, rows.end), &mut planes, wanted);
        self.support.compute(&self.desc_left, &self.desc_right, &sp, region);
        self.support.points(&mut self.points);
        self.grid_left.compute(&self.points, disparities, false);
        self.grid_right.compute(&self.points, disparities, true);
        self.prior.compute(&self.support, (rows.start, rows.end));

        // A left pixel x matches right pixels x - d_max ..= x - d_min, which the left-right
        // check reads back.
        let left_columns = (region.x0.min(w), region.x1.min(w));
        let right_columns =
            (region.x0.saturating_sub(d_max as usize).min(w), region.x1.saturating_sub(d_min as usize).min(w));
        let whole_rows = left_columns == (0, w);
        let left_side = Side {
            own: &self.desc_left,
            other: &self.desc_right,
            prior: &self.prior.left,
            prior_step: step,
            grid: &self.grid_left,
            columns: left_columns,
        };
        let right_side = Side {
            own: &self.desc_right,
            other: &self.desc_left,
            prior: &self.prior.right,
            prior_step: step,
            grid: &self.grid_right,
            columns: right_columns,
        };
        let q = Search {
            range: disparities,
            radius: self.prior_radius,
            min_texture: self.min_texture,
            prior_energy: &self.prior_energy,
            vector: self.vector_prior,
        };
        let lr_tol = self.lr_tolerance;
        let matched = w * h.div_ceil(step);
        let (dense, dense_right) = (&mut self.dense_left[..matched], &mut self.dense_right[..matched]);
        dense.par_chunks_mut(w).zip(dense_right.par_chunks_mut(w)).enumerate().for_each(|(j, (dl, dr))| {
            let y = j * step;
            if y < BORDER || y + BORDER >= h || !rows.contains(&y) {
                dl.fill(INVALID);
                dr.fill(INVALID);
                return;
            }
            if !whole_rows {
                dl.fill(INVALID);
                dr.fill(INVALID);
            }
            match_row::<false>(&right_side, &q, y, dr, kernel);
            match_row::<true>(&left_side, &q, y, dl, kernel);
            // Left-right check: the right pixel a left one lands on must point back.
            for (x, o) in dl.iter_mut().enumerate() {
                let d = *o;
                *o = if d.is_finite() && (dr[x - d as usize] - d).abs() <= lr_tol { d } else { INVALID };
            }
        });

        // A region of n pixels holds about n / step matched ones.
        let speckle_size = self.speckle_size.div_ceil(step);
        remove_speckles(dense, w, speckle_size, self.speckle_similarity, &mut self.speckles);
        refine_subpixel(left, right, dense, step, self.subpixel_radius, (rows.start, rows.end), &mut self.scratch);
        interpolate_gaps(dense, w, self.gap_width, self.gap_width / step);
        // The matched rows into their places; the rows between stay INVALID.
        for (j, row) in dense.chunks_exact(w).enumerate() {
            out.data[j * step * w..(j * step + 1) * w].copy_from_slice(row);
        }
        Ok(())
    }
}
