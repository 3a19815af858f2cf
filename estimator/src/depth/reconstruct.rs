//! The reconstruction workspace (docs/design/estimator-stages.md, steps 1-3): raw shots of both cameras in;
//! rectified images, disparity, depth and the world cloud after background removal out.
//! Everything is allocated in `Reconstructor::new`; `process` reuses it frame after frame.

use std::time::Instant;

use camplace_config::{AsImageView, ImageView};

use crate::{
    Background, Cloud, CloudBuilder, Elas, Error, ErrorKind, EstimatorConfig, FloatImage, Foreground, GrayImage,
    Method, PhaseDecoder, PixelRegion, Rectification, Result, Rig,
};

/// Time spent in each reconstruction stage of the last frame, ms.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ReconstructTimings {
    pub rectify_ms: f64,
    pub disparity_ms: f64,
    pub cloud_ms: f64,
}

/// The caller-owned output of one frame's reconstruction.
#[derive(Debug, Clone, Default)]
pub struct Reconstruction {
    /// Rectified-left disparity, px; +inf invalid.
    pub disparity: FloatImage,
    /// World points after background removal and cropping, with their depth image.
    pub cloud: Cloud,
    pub timings: ReconstructTimings,
}

#[derive(Clone)]
enum Decoder {
    Stereo(Box<Elas>),
    Phase(Box<PhaseDecoder>),
}

/// Rectification, disparity (one-shot stereo or 12-shot phase) and the cloud, for one rig.
#[derive(Clone)]
pub struct Reconstructor {
    method: Method,
    rectification: Rectification,
    decoder: Decoder,
    builder: CloudBuilder,
    background: Option<Background>,
    /// Where the tray can be in a one-shot frame, against the background capture's rectified
    /// left image (none before a background, and for phase-12).
    foreground: Option<Foreground>,
    /// The region the last frame's disparity was computed in.
    region: PixelRegion,
    /// Match every frame whole, background or not (what a depth map written for a person
    /// to read needs).
    whole_image: bool,
    reconstruction: camplace_config::ReconstructionParams,
    raw_left: (usize, usize),
    raw_right: (usize, usize),
    rect_left: Vec<GrayImage>,
    rect_right: Vec<GrayImage>,
    scratch: FloatImage,
    /// The address of the last frame's first left shot's pixels (0 before any).
    last_left: usize,
    /// What the decoder was built from: its settings, the canvas and the disparity span.
    decoder_for: DecoderFor,
}

/// The settings, canvas size and disparity span a decoder's buffers were sized for.
#[derive(Clone, PartialEq)]
struct DecoderFor {
    stereo: camplace_config::StereoParams,
    phase: camplace_config::PhaseParams,
    fringe_periods: Vec<f64>,
    canvas: (usize, usize),
    span: usize,
}

impl DecoderFor {
    fn new(config: &EstimatorConfig, rectification: &Rectification) -> DecoderFor {
        let (lo, hi) = rectification.disparity_range();
        DecoderFor {
            stereo: config.stereo.clone(),
            phase: config.phase.clone(),
            fringe_periods: config.fringe_periods.clone(),
            canvas: (rectification.camera.width, rectification.camera.height),
            span: (hi - lo).ceil().max(1.0) as usize + 1,
        }
    }

    fn decoder(&self, method: Method) -> Result<Decoder> {
        let (w, h) = self.canvas;
        Ok(match method {
            Method::OneShot => Decoder::Stereo(Box::new(Elas::new(&self.stereo, w, h, self.span))),
            Method::Phase12 => Decoder::Phase(Box::new(PhaseDecoder::new(&self.phase, &self.fringe_periods, w, h)?)),
        })
    }
}

impl Reconstructor {
    /// The workspace for `rig` with the cell's work volume and settings.
    pub fn new(config: &EstimatorConfig, rig: &Rig, method: Method) -> Result<Reconstructor> {
        Self::with_rectification(config, rig, method, Rectification::new(rig, &config.work_volume)?)
    }

    /// The workspace around a rectification of `rig` made already.
    fn with_rectification(
        config: &EstimatorConfig,
        rig: &Rig,
        method: Method,
        rectification: Rectification,
    ) -> Result<Reconstructor> {
        let cam = &rectification.camera;
        let (w, h) = (cam.width, cam.height);
        let decoder_for = DecoderFor::new(config, &rectification);
        let decoder = decoder_for.decoder(method)?;
        let shots = method.shots(config.fringe_periods.len());
        Ok(Reconstructor {
            method,
            builder: CloudBuilder::new(cam, &config.work_volume, &config.reconstruction),
            decoder,
            background: None,
            foreground: None,
            region: PixelRegion::whole(w, h),
            whole_image: false,
            reconstruction: config.reconstruction.clone(),
            raw_left: (rig.left.width, rig.left.height),
            raw_right: (rig.right.width, rig.right.height),
            rect_left: vec![GrayImage::new(w, h, 0); shots],
            rect_right: vec![GrayImage::new(w, h, 0); shots],
            scratch: FloatImage::new(w, h, f32::INFINITY),
            last_left: 0,
            rectification,
            decoder_for,
        })
    }

    /// Moves the workspace to `rig` (the same cameras calibrated anew): a new rectification
    /// and cloud builder, with the decoder's and the images' buffers kept when the settings,
    /// the canvas and the disparity span are unchanged (they hold nothing from one frame to
    /// the next), else everything as [`Reconstructor::new`] builds it. The background is
    /// dropped: it must be captured again through the new rig.
    pub fn set_rig(&mut self, config: &EstimatorConfig, rig: &Rig) -> Result<()> {
        let rectification = Rectification::new(rig, &config.work_volume)?;
        let decoder_for = DecoderFor::new(config, &rectification);
        let shots = self.method.shots(config.fringe_periods.len());
        if decoder_for != self.decoder_for || shots != self.rect_left.len() {
            *self = Reconstructor::with_rectification(config, rig, self.method, rectification)?;
            return Ok(());
        }
        self.builder = CloudBuilder::new(&rectification.camera, &config.work_volume, &config.reconstruction);
        self.background = None;
        self.foreground = None;
        self.reconstruction = config.reconstruction.clone();
        self.raw_left = (rig.left.width, rig.left.height);
        self.raw_right = (rig.right.width, rig.right.height);
        self.rectification = rectification;
        Ok(())
    }

    /// The rectification (the shared rectified camera and the disparity search range).
    pub fn rectification(&self) -> &Rectification {
        &self.rectification
    }

    /// The capture method.
    pub fn method(&self) -> Method {
        self.method
    }

    /// The rectified images of the last frame (one or twelve per side).
    pub fn rectified(&self) -> (&[GrayImage], &[GrayImage]) {
        (&self.rect_left, &self.rect_right)
    }

    /// Where the last frame's first left shot began in memory (0 before any frame).
    pub fn last_left_address(&self) -> usize {
        self.last_left
    }

    /// The background, once captured.
    pub fn background(&self) -> Option<&Background> {
        self.background.as_ref()
    }

    /// Reconstructs the background capture (the cell without tray and items) and keeps it,
    /// dilated, for background removal in every later frame.
    ///
    /// A one-shot background also sets where later frames are matched: the box of the
    /// rectified left image that differs from this capture ([`Foreground`]).
    pub fn set_background<S: AsImageView<u8>>(&mut self, left: &[S], right: &[S]) -> Result<()> {
        self.foreground = None;
        let mut disparity = std::mem::take(&mut self.scratch);
        let result = self.disparity(left, right, &mut disparity, &mut ReconstructTimings::default());
        let background = result
            .and_then(|_| Background::from_disparity(&self.rectification.camera, &disparity, &self.reconstruction));
        self.scratch = disparity;
        self.background = Some(background?);
        if self.method == Method::OneShot {
            self.foreground = Some(Foreground::new(self.rect_left[0].clone()));
        }
        Ok(())
    }

    /// Matches every later frame over the whole image (`true`), or only where it differs
    /// from a one-shot background (`false`, the default: the estimator's way).
    pub fn set_whole_image(&mut self, whole: bool) {
        self.whole_image = whole;
    }

    /// The region of the rectified left image the last frame's disparity was computed in.
    pub fn last_region(&self) -> PixelRegion {
        self.region
    }

    /// Whether the last frame was matched over the whole image (a 12-shot frame, a frame
    /// without a background, or one that differs from the background everywhere).
    pub fn matched_whole(&self) -> bool {
        self.region == PixelRegion::whole(self.rectification.camera.width, self.rectification.camera.height)
    }

    /// Matches the last one-shot frame again over the whole image when it was matched in a
    /// region only, into a map of its own ([`Reconstructor::whole_map`]); returns whether it
    /// did. A frame already matched whole (or a 12-shot frame) is left as it is.
    pub fn match_whole(&mut self) -> Result<bool> {
        let (w, h) = (self.rectification.camera.width, self.rectification.camera.height);
        if self.matched_whole() {
            return Ok(false);
        }
        let Decoder::Stereo(elas) = &mut self.decoder else { return Ok(false) };
        let range = self.rectification.disparity_range();
        elas.compute_in(&self.rect_left[0], &self.rect_right[0], range, PixelRegion::whole(w, h), &mut self.scratch)?;
        Ok(true)
    }

    /// The map of the last [`Reconstructor::match_whole`] that matched.
    pub fn whole_map(&self) -> &FloatImage {
        &self.scratch
    }

    /// Reconstructs one frame into `out`.
    pub fn process<S: AsImageView<u8>>(&mut self, left: &[S], right: &[S], out: &mut Reconstruction) -> Result<()> {
        let mut timings = ReconstructTimings::default();
        self.disparity(left, right, &mut out.disparity, &mut timings)?;
        let t = Instant::now();
        self.builder.build(&out.disparity, self.background.as_ref(), &mut out.cloud)?;
        timings.cloud_ms = ms(t);
        out.timings = timings;
        Ok(())
    }

    fn disparity<S: AsImageView<u8>>(
        &mut self,
        left: &[S],
        right: &[S],
        out: &mut FloatImage,
        timings: &mut ReconstructTimings,
    ) -> Result<()> {
        let shots = self.rect_left.len();
        if left.len() != shots || right.len() != shots {
            return Err(Error::new(
                ErrorKind::Input,
                format!(
                    "{}: expected {shots} left and {shots} right images, got {} and {}",
                    self.method,
                    left.len(),
                    right.len()
                ),
            ));
        }
        for (i, img) in left.iter().enumerate() {
            check_size("left", i, img.as_view(), self.raw_left)?;
        }
        for (i, img) in right.iter().enumerate() {
            check_size("right", i, img.as_view(), self.raw_right)?;
        }
        self.last_left = left.first().map_or(0, |s| s.as_view().data().as_ptr() as usize);
        let t = Instant::now();
        self.rectification.rectify_left_shots(left, &mut self.rect_left);
        self.rectification.rectify_right_shots(right, &mut self.rect_right);
        timings.rectify_ms = ms(t);
        let t = Instant::now();
        let range = self.rectification.disparity_range();
        match &mut self.decoder {
            Decoder::Stereo(elas) => {
                let (w, h) = (self.rect_left[0].width, self.rect_left[0].height);
                self.region = match &mut self.foreground {
                    Some(f) if !self.whole_image => f.region(&self.rect_left[0]),
                    _ => PixelRegion::whole(w, h),
                };
                elas.compute_in(&self.rect_left[0], &self.rect_right[0], range, self.region, out)?
            }
            Decoder::Phase(phase) => {
                self.region = PixelRegion::whole(self.rect_left[0].width, self.rect_left[0].height);
                phase.decode(&self.rect_left, &self.rect_right, range, out)?
            }
        }
        timings.disparity_ms = ms(t);
        Ok(())
    }
}

fn check_size(side: &str, shot: usize, img: ImageView<'_, u8>, (width, height): (usize, usize)) -> Result<()> {
    if img.width() != width || img.height() != height {
        return Err(Error::new(
            ErrorKind::Input,
            format!(
                "{side} image {shot}: expected {width} x {height} pixels (the rig), got {} x {}",
                img.width(),
                img.height()
            ),
        ));
    }
    Ok(())
}

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}
