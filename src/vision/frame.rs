//! Stereo frames: loading side-by-side or separate images, their coarse pyramid levels,
//! and the per-pixel colour data of the paper (one colour code, saturation and raw hue
//! per pixel) that [`crate::vision::lookup`] packs for the fitness.

use std::path::{Path, PathBuf};

use image::{imageops, RgbImage};
use rayon::prelude::*;

use nalgebra::{Isometry3, Point3};

use crate::camera::{Intrinsics, StereoRig};
use crate::vision::color::{rgb_to_hsv, ColorClasses};
use crate::vision::lookup::gained;

/// A problem reading a frame.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    /// The image file could not be opened or decoded.
    #[error("cannot read image {path}: {message}")]
    Image {
        /// The image file.
        path: PathBuf,
        /// The reader's or decoder's message, on one line.
        message: String,
    },
    /// A side-by-side image of odd width cannot be split into two equal eyes.
    #[error("{path}: side-by-side frame width {width} is odd (left and right halves must match)")]
    OddWidth {
        /// The image file.
        path: PathBuf,
        /// Its width, pixels.
        width: u32,
    },
    /// The separate left and right images differ in size.
    #[error("{left} is {lw}x{lh} but {right} is {rw}x{rh}: both eyes must have the same size")]
    SizeMismatch {
        /// The left image file.
        left: PathBuf,
        /// The right image file.
        right: PathBuf,
        /// Left image width, pixels.
        lw: u32,
        /// Left image height, pixels.
        lh: u32,
        /// Right image width, pixels.
        rw: u32,
        /// Right image height, pixels.
        rh: u32,
    },
}

/// The left and right images of one stereo frame.
#[derive(Debug, Clone)]
pub struct StereoImages {
    /// The left eye's image.
    pub left: RgbImage,
    /// The right eye's image, the same size.
    pub right: RgbImage,
}

fn read_rgb(path: &Path) -> Result<RgbImage, FrameError> {
    // Decoder messages may span lines; errors here are one line.
    let error = |e: &dyn std::fmt::Display| FrameError::Image {
        path: path.to_path_buf(),
        message: e.to_string().trim().replace('\n', "; "),
    };
    let img = image::ImageReader::open(path)
        .map_err(|e| error(&e))?
        .with_guessed_format()
        .map_err(|e| error(&e))?
        .decode()
        .map_err(|e| error(&e))?;
    Ok(img.to_rgb8())
}

/// Reads any image the `image` crate decodes (PNG, JPEG) as RGB8.
pub fn load_rgb(path: &Path) -> Result<RgbImage, FrameError> {
    read_rgb(path)
}

impl StereoImages {
    /// Both eyes with every pixel scaled by `gains` `[r, g, b]`, clipped pixels kept (see
    /// [`crate::vision::lookup::gained`]).
    pub fn apply_gains(&mut self, gains: [f32; 3]) {
        if gains == [1.0; 3] {
            return;
        }
        for px in self.left.pixels_mut().chain(self.right.pixels_mut()) {
            let rgb = gained(px.0.map(f32::from), gains);
            px.0 = rgb.map(|c| c.round() as u8);
        }
    }

    /// Splits a side-by-side image (left eye in the left half).
    pub fn from_sbs(sbs: &RgbImage, path: &Path) -> Result<Self, FrameError> {
        let (w, h) = sbs.dimensions();
        if w % 2 != 0 {
            return Err(FrameError::OddWidth {
                path: path.to_path_buf(),
                width: w,
            });
        }
        let half = w / 2;
        Ok(Self {
            left: imageops::crop_imm(sbs, 0, 0, half, h).to_image(),
            right: imageops::crop_imm(sbs, half, 0, half, h).to_image(),
        })
    }

    /// Reads a side-by-side frame file.
    pub fn load_sbs(path: &Path) -> Result<Self, FrameError> {
        Self::from_sbs(&read_rgb(path)?, path)
    }

    /// Reads separate left and right images.
    pub fn load_pair(left: &Path, right: &Path) -> Result<Self, FrameError> {
        let (l, r) = (read_rgb(left)?, read_rgb(right)?);
        if l.dimensions() != r.dimensions() {
            return Err(FrameError::SizeMismatch {
                left: left.to_path_buf(),
                right: right.to_path_buf(),
                lw: l.width(),
                lh: l.height(),
                rw: r.width(),
                rh: r.height(),
            });
        }
        Ok(Self { left: l, right: r })
    }

    /// Joins the eyes into one side-by-side image.
    pub fn to_sbs(&self) -> RgbImage {
        let (w, h) = self.left.dimensions();
        let mut out = RgbImage::new(2 * w, h);
        imageops::replace(&mut out, &self.left, 0, 0);
        imageops::replace(&mut out, &self.right, w as i64, 0);
        out
    }

    /// Size of one eye.
    pub fn eye_size(&self) -> (u32, u32) {
        self.left.dimensions()
    }
}

/// A rectangle of one eye's pixels.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Region {
    /// Columns (x), pixels from the eye's left edge.
    pub cols: std::ops::Range<usize>,
    /// Rows (y), pixels from the eye's top edge.
    pub rows: std::ops::Range<usize>,
}

impl Region {
    /// The whole of a `width × height` image.
    pub fn all(width: usize, height: usize) -> Self {
        Region {
            cols: 0..width,
            rows: 0..height,
        }
    }

    /// Pixels of a `width × height` image covered by flat rectangles (camera-frame poses,
    /// centred, sizes in mm) seen through `cam`, grown on every side by `pad(extent)`
    /// pixels, `extent` being the larger side of their projected box. The whole image
    /// when a rectangle reaches behind the camera.
    pub fn covering(
        cam: &Intrinsics,
        cam_from_rects: impl IntoIterator<Item = (Isometry3<f64>, [f64; 2])>,
        width: usize,
        height: usize,
        pad: impl Fn(f64) -> f64,
    ) -> Self {
        let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
        for (cam_from_rect, [sx, sy]) in cam_from_rects {
            // Corners and edge midpoints: distortion bends the edges.
            for (fx, fy) in [(-1, -1), (0, -1), (1, -1), (1, 0), (1, 1), (0, 1), (-1, 1), (-1, 0)] {
                let p = cam_from_rect * Point3::new(0.5 * sx * fx as f64, 0.5 * sy * fy as f64, 0.0);
                let Some(q) = cam.project(&p) else {
                    return Self::all(width, height);
                };
                lo = [lo[0].min(q.x), lo[1].min(q.y)];
                hi = [hi[0].max(q.x), hi[1].max(q.y)];
            }
        }
        let pad = pad((hi[0] - lo[0]).max(hi[1] - lo[1]));
        let span = |a: f64, b: f64, n: usize| {
            let a = (a - pad).floor().clamp(0.0, n as f64) as usize;
            let b = (b + pad).ceil().clamp(0.0, n as f64) as usize;
            a..b.max(a)
        };
        Region {
            cols: span(lo[0], hi[0], width),
            rows: span(lo[1], hi[1], height),
        }
    }
}

/// The colour data of one pixel, interleaved so one memory access serves a sample point.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PixelColor {
    /// [`crate::vision::color`] code: the hue of a chromatic pixel, or the achromatic class.
    pub code: u8,
    /// Saturation.
    pub sat: u8,
    /// Raw OpenCV hue (0 for pure grey, as OpenCV gives).
    pub hue: u8,
}

/// Colour data of one image, row-major (computed on all cores).
#[derive(Debug, Clone)]
pub struct ColorPlane {
    /// Width, pixels.
    pub width: usize,
    /// Height, pixels.
    pub height: usize,
    /// The pixels' colour data, `width × height`, row-major.
    pub px: Vec<PixelColor>,
}

impl ColorPlane {
    /// The colour data of `img`: OpenCV HSV and its Table 1 class under `classes`.
    pub fn from_rgb(img: &RgbImage, classes: &ColorClasses) -> Self {
        let px = img
            .as_raw()
            .par_chunks_exact(3)
            .map(|p| {
                let (hue, sat, v) = rgb_to_hsv(p[0], p[1], p[2]);
                PixelColor {
                    code: classes.code(hue, sat, v),
                    sat,
                    hue,
                }
            })
            .collect();
        Self {
            width: img.width() as usize,
            height: img.height() as usize,
            px,
        }
    }
}

/// One pyramid level: the rig scaled to it and both colour planes.
#[derive(Debug, Clone)]
pub struct FrameLevel {
    /// Image scale relative to full resolution (1, 1/2, 1/4, …).
    pub scale: f64,
    /// The stereo rig with its intrinsics scaled to this level's pixels.
    pub rig: StereoRig,
    /// The left image's colour data at this level.
    pub left: ColorPlane,
    /// The right image's colour data at this level.
    pub right: ColorPlane,
}

/// The coarse pyramid levels 1.. of a stereo frame (`levels` in all, counting the frame
/// itself as level 0): each level averages 2×2 blocks of the one above and is then
/// blurred a little more, like the model's thumbnail colours.
pub fn coarse_levels(images: &StereoImages, levels: usize) -> Vec<StereoImages> {
    let (mut l, mut r) = (images.left.clone(), images.right.clone());
    (1..levels)
        .map(|_| {
            l = half(&l);
            r = half(&r);
            StereoImages {
                left: blur3(&l),
                right: blur3(&r),
            }
        })
        .collect()
}

/// 3×3 box blur (edges clamped): a horizontal then a vertical 3-tap sum.
fn blur3(img: &RgbImage) -> RgbImage {
    let (w, h) = (img.width() as usize, img.height() as usize);
    let src = img.as_raw();
    let mut rows = vec![0u16; w * h * 3];
    for y in 0..h {
        for x in 0..w {
            let (l, r) = (x.saturating_sub(1), (x + 1).min(w - 1));
            for c in 0..3 {
                let at = |xx: usize| src[(y * w + xx) * 3 + c] as u16;
                rows[(y * w + x) * 3 + c] = at(l) + at(x) + at(r);
            }
        }
    }
    let mut out = vec![0u8; w * h * 3];
    for y in 0..h {
        let (u, d) = (y.saturating_sub(1), (y + 1).min(h - 1));
        for i in 0..w * 3 {
            let sum = rows[u * w * 3 + i] + rows[y * w * 3 + i] + rows[d * w * 3 + i];
            out[y * w * 3 + i] = (sum / 9) as u8;
        }
    }
    RgbImage::from_raw(w as u32, h as u32, out).expect("buffer of the image's size")
}

/// Halves an image by averaging 2×2 blocks (an odd last row or column is dropped).
fn half(img: &RgbImage) -> RgbImage {
    let (sw, sh) = (img.width() as usize, img.height() as usize);
    let (w, h) = ((sw / 2).max(1), (sh / 2).max(1));
    let src = img.as_raw();
    let mut out = vec![0u8; w * h * 3];
    for y in 0..h {
        let (y0, y1) = ((2 * y).min(sh - 1), (2 * y + 1).min(sh - 1));
        for x in 0..w {
            let (x0, x1) = ((2 * x).min(sw - 1), (2 * x + 1).min(sw - 1));
            for c in 0..3 {
                let at = |xx: usize, yy: usize| src[(yy * sw + xx) * 3 + c] as u32;
                out[(y * w + x) * 3 + c] = ((at(x0, y0) + at(x1, y0) + at(x0, y1) + at(x1, y1)) / 4) as u8;
            }
        }
    }
    RgbImage::from_raw(w as u32, h as u32, out).expect("buffer of the image's size")
}

#[cfg(test)]
mod tests {
    use super::*;
    use image::Rgb;

    #[test]
    fn side_by_side_splits_into_eyes() {
        let mut sbs = RgbImage::from_pixel(8, 2, Rgb([10, 10, 10]));
        sbs.put_pixel(4, 1, Rgb([255, 0, 0]));
        let st = StereoImages::from_sbs(&sbs, Path::new("f.png")).unwrap();
        assert_eq!(st.eye_size(), (4, 2));
        assert_eq!(st.right.get_pixel(0, 1).0, [255, 0, 0]);
        assert_eq!(st.to_sbs(), sbs);
        let odd = RgbImage::new(7, 2);
        let e = StereoImages::from_sbs(&odd, Path::new("f.png"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("f.png") && e.contains("odd"), "{e}");
    }

    #[test]
    fn missing_or_corrupt_image_names_the_file() {
        let e = StereoImages::load_sbs(Path::new("/nonexistent/frame.png"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("frame.png"), "{e}");
        let p = std::env::temp_dir().join(format!("photopose-corrupt-{}.png", std::process::id()));
        std::fs::write(&p, b"\x89PNG\r\n\x1a\nnot really").unwrap();
        let e = StereoImages::load_sbs(&p).unwrap_err().to_string();
        assert!(
            e.contains("photopose-corrupt") && e.starts_with("cannot read image"),
            "{e}"
        );
        std::fs::remove_file(&p).unwrap();
    }

    #[test]
    fn colour_plane_codes_pixels() {
        let img = RgbImage::from_fn(
            2,
            1,
            |x, _| if x == 0 { Rgb([0, 0, 255]) } else { Rgb([250, 250, 250]) },
        );
        let p = ColorPlane::from_rgb(&img, &ColorClasses::default());
        let codes: Vec<u8> = p.px.iter().map(|c| c.code).collect();
        let hues: Vec<u8> = p.px.iter().map(|c| c.hue).collect();
        assert_eq!(codes, vec![120, crate::vision::color::WHITE]);
        assert_eq!(hues, vec![120, 0]);
    }
}
