//! Pixel formats of a frame's bytes: RGB8, or YUYV as the ZED 2i sends over UVC.

/// A frame payload's pixel format as a type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PixelFormat {
    /// 3 bytes per pixel, R G B.
    Rgb8,
    /// 2 bytes per pixel, Y0 U Y1 V.
    Yuyv,
}

impl PixelFormat {
    /// Bytes per pixel.
    pub fn bytes_per_pixel(self) -> usize {
        match self {
            PixelFormat::Rgb8 => 3,
            PixelFormat::Yuyv => 2,
        }
    }

    /// `"RGB8"` or `"YUYV"`, as in files.
    pub fn name(self) -> &'static str {
        match self {
            PixelFormat::Rgb8 => "RGB8",
            PixelFormat::Yuyv => "YUYV",
        }
    }

    /// Parses [`PixelFormat::name`] (case-insensitive).
    pub fn parse(name: &str) -> Option<Self> {
        [PixelFormat::Rgb8, PixelFormat::Yuyv]
            .into_iter()
            .find(|f| f.name().eq_ignore_ascii_case(name.trim()))
    }
}
