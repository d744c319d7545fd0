//! A minimal CDR writer: XCDR1 (plain CDR), little-endian, as rmw_zenoh and every DDS
//! RMW serialise ROS 2 messages.
//!
//! The payload starts with the 4-byte encapsulation header `00 01 00 00`; primitives are
//! aligned to their size, counted from the byte after that header. Strings are a `u32`
//! length that includes the terminating NUL, the bytes, then the NUL.

/// The encapsulation header of little-endian plain CDR.
pub const ENCAPSULATION_LE: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Appends CDR-encoded values to a buffer it has cleared and headed.
pub struct CdrWriter<'a> {
    buf: &'a mut Vec<u8>,
}

impl<'a> CdrWriter<'a> {
    /// Clears `buf` and writes the encapsulation header (the buffer keeps its capacity).
    pub fn new(buf: &'a mut Vec<u8>) -> Self {
        buf.clear();
        buf.extend_from_slice(&ENCAPSULATION_LE);
        Self { buf }
    }

    /// Pads with zeros to a multiple of `n` bytes after the header.
    fn align(&mut self, n: usize) {
        let body = self.buf.len() - ENCAPSULATION_LE.len();
        let pad = (n - body % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }

    /// An `octet`, `byte`, `char` or `bool`.
    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.buf.push(v);
        self
    }

    /// An `uint32`.
    pub fn u32(&mut self, v: u32) -> &mut Self {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// An `int32`.
    pub fn i32(&mut self, v: i32) -> &mut Self {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// A `float64`.
    pub fn f64(&mut self, v: f64) -> &mut Self {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
        self
    }

    /// A `string`: the length with the NUL, the bytes, the NUL.
    ///
    /// Panics for strings of 4 GiB or more, which no message of this crate holds.
    pub fn string(&mut self, s: &str) -> &mut Self {
        let len = u32::try_from(s.len() + 1).unwrap_or_else(|_| panic!("CDR string of {} bytes", s.len()));
        self.u32(len);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
        self
    }

    /// The length of a sequence, before its elements.
    pub fn sequence_len(&mut self, len: usize) -> &mut Self {
        let len = u32::try_from(len).unwrap_or_else(|_| panic!("CDR sequence of {len} elements"));
        self.u32(len)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn alignment_counts_from_after_the_header() {
        let mut buf = Vec::new();
        CdrWriter::new(&mut buf).u8(7).u32(1).u8(2).f64(1.5);
        let mut want = vec![0, 1, 0, 0, 7, 0, 0, 0, 1, 0, 0, 0, 2, 0, 0, 0, 0, 0, 0, 0];
        want.extend_from_slice(&1.5f64.to_le_bytes());
        assert_eq!(buf, want);
    }

    #[test]
    fn strings_carry_their_nul() {
        let mut buf = Vec::new();
        CdrWriter::new(&mut buf).string("ab").string("");
        assert_eq!(buf, [0, 1, 0, 0, 3, 0, 0, 0, b'a', b'b', 0, 0, 1, 0, 0, 0, 0]);
    }

    #[test]
    fn a_writer_reuses_its_buffer() {
        let mut buf = vec![9; 100];
        CdrWriter::new(&mut buf).i32(-1);
        assert_eq!(buf, [0, 1, 0, 0, 255, 255, 255, 255]);
    }
}
