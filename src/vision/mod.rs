//! Image data as the fitness reads it: colour classes and HSV ([`color`]), stereo frames
//! and their pyramid ([`frame`]), and lookup images packed for the kernel ([`lookup`]).

pub mod color;
pub mod frame;
pub mod lookup;
mod pixel;

pub use pixel::PixelFormat;
