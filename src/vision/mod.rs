//! Image data as the fitness reads it: colour classes and HSV ([`color`]), stereo frames
//! and their pyramid ([`frame`]), and lookup images packed for the kernel ([`lookup`]);
//! the hot loops' choice of instruction set (`simd`, inside the crate).

pub mod color;
pub mod frame;
pub mod lookup;
mod pixel;
pub(crate) mod simd;

pub use pixel::PixelFormat;
