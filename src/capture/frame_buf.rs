//! Writing a frame into memory that may not be initialised yet: a shared-memory sample
//! loaned with `loan_slice_uninit`, so publishing an HD frame does not first zero
//! megabytes that the source then overwrites.
//!
//! A [`FrameSource`] gets a [`FrameBuf`] and must hand back a [`Written`], which only
//! [`FrameBuf`]'s methods make and only after writing every byte; [`write_uninit`]
//! checks that the proof is for the buffer it lent. Sources never see uninitialised
//! bytes as `u8` and cannot hand back a buffer they did not fill, so the caller can
//! take the sample as initialised without trusting each source.

use std::mem::MaybeUninit;

use super::{FrameInfo, FrameSource, SourceError};

/// The buffer a frame is written into: [`Geometry::frame_len`](super::Geometry::frame_len)
/// bytes, possibly uninitialised.
#[derive(Debug)]
pub struct FrameBuf<'a> {
    /// Private: only ever written with initialised bytes, so wrapping an initialised
    /// `&mut [u8]` ([`FrameBuf::from_init`]) is sound.
    bytes: &'a mut [MaybeUninit<u8>],
}

/// Proof that every byte of a [`FrameBuf`] has been written, and the written bytes.
#[derive(Debug)]
pub struct Written<'a>(&'a mut [u8]);

impl<'a> FrameBuf<'a> {
    /// Wraps memory that may be uninitialised (e.g. a loaned sample's payload).
    pub fn uninit(bytes: &'a mut [MaybeUninit<u8>]) -> Self {
        Self { bytes }
    }

    /// Wraps an initialised buffer (e.g. a `Vec<u8>` reused for every frame).
    pub fn from_init(bytes: &'a mut [u8]) -> Self {
        // SAFETY: `MaybeUninit<u8>` has the layout of `u8`; `FrameBuf` only ever writes
        // initialised bytes into it, so `bytes` is still initialised when its borrow ends.
        let bytes = unsafe { &mut *(std::ptr::from_mut::<[u8]>(bytes) as *mut [MaybeUninit<u8>]) };
        Self { bytes }
    }

    /// Bytes in the buffer.
    pub fn len(&self) -> usize {
        self.bytes.len()
    }

    /// True for a zero-length buffer.
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// Copies a whole frame in: `src` must be exactly [`FrameBuf::len`] bytes.
    pub fn copy_from(self, src: &[u8]) -> Result<Written<'a>, SourceError> {
        if src.len() != self.bytes.len() {
            return Err(SourceError::BufferSize {
                buffer: self.bytes.len(),
                frame: src.len(),
            });
        }
        // SAFETY: same length, checked above; `u8` and `MaybeUninit<u8>` have the same
        // layout; the two cannot overlap, as `self.bytes` is borrowed mutably.
        unsafe { std::ptr::copy_nonoverlapping(src.as_ptr(), self.bytes.as_mut_ptr().cast::<u8>(), src.len()) };
        // SAFETY: every byte was written just above.
        Ok(Written(unsafe { assume_init(self.bytes) }))
    }
}

impl Written<'_> {
    /// The frame's bytes.
    pub fn bytes(&self) -> &[u8] {
        self.0
    }

    /// The frame's bytes, to write in place.
    pub fn bytes_mut(&mut self) -> &mut [u8] {
        self.0
    }
}

/// # Safety
/// Every byte of `bytes` must be initialised.
unsafe fn assume_init(bytes: &mut [MaybeUninit<u8>]) -> &mut [u8] {
    // SAFETY: same layout; the caller guarantees initialisation.
    unsafe { &mut *(std::ptr::from_mut::<[MaybeUninit<u8>]>(bytes) as *mut [u8]) }
}

/// Has `source` write its due frame into `buf`, which may be uninitialised. `Some`
/// only when every byte of `buf` was written, so the caller may then treat `buf` as
/// initialised (e.g. `assume_init` a loaned sample).
pub fn write_uninit(
    source: &mut dyn FrameSource,
    buf: &mut [MaybeUninit<u8>],
) -> Result<Option<FrameInfo>, SourceError> {
    let (start, len) = (buf.as_ptr().cast::<u8>(), buf.len());
    let Some((info, written)) = source.write_frame(FrameBuf::uninit(buf))? else {
        return Ok(None);
    };
    // A `Written` for some other buffer proves nothing about this one.
    if std::ptr::eq(written.0.as_ptr(), start) && written.0.len() == len {
        Ok(Some(info))
    } else {
        Err(SourceError::Setup(format!(
            "{} did not write the frame into the buffer it was given",
            source.describe()
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_frame_buf_writes_every_byte() {
        let mut mem = [MaybeUninit::<u8>::uninit(); 6];
        let w = FrameBuf::uninit(&mut mem).copy_from(&[1, 2, 3, 4, 5, 6]).unwrap();
        assert_eq!(w.bytes(), [1, 2, 3, 4, 5, 6]);
        let e = FrameBuf::uninit(&mut mem).copy_from(&[1, 2]).unwrap_err().to_string();
        assert!(e.contains("6-byte buffer") && e.contains("2-byte frame"), "{e}");
        // An initialised buffer is written through.
        let mut vec = vec![7u8; 4];
        assert_eq!(FrameBuf::from_init(&mut vec).len(), 4);
        FrameBuf::from_init(&mut vec).copy_from(&[1, 2, 3, 4]).unwrap();
        assert_eq!(vec, [1, 2, 3, 4]);
    }
}
