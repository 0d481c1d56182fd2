//! MSB-first bit streams for the interpolative coder and the plain binary
//! form, and LEB128 varints for container headers.
//!
//! The reader never fails mid-stream: reading past the end yields zero bits
//! and sets a flag the caller checks once at the end. Every loop that reads is
//! bounded by a count validated beforehand, so truncated input cannot make a
//! decoder spin, and the hot loop carries no error branches.

use super::ChainError;

/// Appends bits, most significant first.
#[derive(Debug, Default)]
pub(crate) struct BitWriter {
    bytes: Vec<u8>,
    acc: u64,
    /// Bits held in `acc` (always < 8 between calls).
    pending: u32,
}

impl BitWriter {
    pub(crate) fn new() -> Self {
        Self::default()
    }

    /// Writes the low `count` bits of `value` (`count` ≤ 64).
    pub(crate) fn write(&mut self, value: u64, count: u32) {
        if count > 32 {
            self.write_small(value >> 32, count - 32);
            self.write_small(value & 0xFFFF_FFFF, 32);
        } else {
            self.write_small(value, count);
        }
    }

    fn write_small(&mut self, value: u64, count: u32) {
        debug_assert!(count <= 32);
        if count == 0 {
            return;
        }
        let masked = value & ((1u64 << count) - 1);
        self.acc = (self.acc << count) | masked;
        self.pending += count;
        while self.pending >= 8 {
            self.pending -= 8;
            self.bytes.push((self.acc >> self.pending) as u8);
        }
        self.acc &= (1u64 << self.pending) - 1;
    }

    /// Total bits written so far.
    pub(crate) fn bit_len(&self) -> u64 {
        self.bytes.len() as u64 * 8 + u64::from(self.pending)
    }

    /// Pads the last byte with zero bits and returns the bytes.
    pub(crate) fn finish(mut self) -> Vec<u8> {
        if self.pending > 0 {
            let pad = 8 - self.pending;
            self.write_small(0, pad);
        }
        self.bytes
    }
}

/// Where an encoder's bits go: a [`BitWriter`] keeps them, a
/// [`BitCounter`] only counts them. The encoders compare several choices
/// (step predictions, stream centres, radius layouts) by their size before
/// writing one; counting is all that comparison needs.
pub(crate) trait BitSink {
    /// Writes the low `count` bits of `value` (`count` ≤ 64).
    fn write(&mut self, value: u64, count: u32);
    /// Total bits written so far.
    fn bit_len(&self) -> u64;
}

impl BitSink for BitWriter {
    fn write(&mut self, value: u64, count: u32) {
        BitWriter::write(self, value, count);
    }

    fn bit_len(&self) -> u64 {
        BitWriter::bit_len(self)
    }
}

/// Counts the bits written to it and keeps none.
#[derive(Debug, Default)]
pub(crate) struct BitCounter {
    bits: u64,
}

impl BitSink for BitCounter {
    fn write(&mut self, _value: u64, count: u32) {
        self.bits += u64::from(count);
    }

    fn bit_len(&self) -> u64 {
        self.bits
    }
}

/// Reads bits, most significant first.
#[derive(Debug)]
pub(crate) struct BitReader<'a> {
    bytes: &'a [u8],
    /// Next bit position.
    pos: u64,
    overrun: bool,
}

impl<'a> BitReader<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Self {
            bytes,
            pos: 0,
            overrun: false,
        }
    }

    /// Reads `count` ≤ 64 bits as an unsigned value.
    #[inline]
    pub(crate) fn read(&mut self, count: u32) -> u64 {
        if count > 32 {
            let high = self.read_small(count - 32);
            (high << 32) | self.read_small(32)
        } else {
            self.read_small(count)
        }
    }

    #[inline]
    fn read_small(&mut self, count: u32) -> u64 {
        if count == 0 {
            return 0;
        }
        let byte = (self.pos / 8) as usize;
        let shift = (self.pos % 8) as u32;
        // Eight bytes hold any 32-bit read at any bit offset.
        let word = self.window(byte);
        let end_bit = self.pos + u64::from(count);
        if end_bit > self.bytes.len() as u64 * 8 {
            self.overrun = true;
        }
        self.pos = end_bit;
        (word << shift) >> (64 - count)
    }

    /// The next `count` bits (1 ≤ `count` ≤ 57) without consuming them;
    /// bits past the end read as zeros.
    #[inline]
    pub(crate) fn peek(&self, count: u32) -> u64 {
        debug_assert!((1..=57).contains(&count));
        let byte = (self.pos / 8) as usize;
        let shift = (self.pos % 8) as u32;
        (self.window(byte) << shift) >> (64 - count)
    }

    /// Consumes `count` bits, as a read would.
    #[inline]
    pub(crate) fn skip(&mut self, count: u32) {
        let end_bit = self.pos + u64::from(count);
        if end_bit > self.bytes.len() as u64 * 8 {
            self.overrun = true;
        }
        self.pos = end_bit;
    }

    /// The eight bytes from `byte` as a big-endian word; missing bytes near
    /// the end read as zeros.
    #[inline]
    fn window(&self, byte: usize) -> u64 {
        match self.bytes.get(byte..byte + 8) {
            Some(b) => u64::from_be_bytes(b.try_into().expect("eight bytes")),
            None => {
                let mut window = [0u8; 8];
                let tail = self.bytes.get(byte..).unwrap_or(&[]);
                window[..tail.len()].copy_from_slice(tail);
                u64::from_be_bytes(window)
            }
        }
    }

    /// Reads one bit.
    #[inline]
    pub(crate) fn bit(&mut self) -> u64 {
        self.read_small(1)
    }

    /// True if any read went past the end of the bytes.
    pub(crate) fn overrun(&self) -> bool {
        self.overrun
    }

    /// Bytes touched so far (the padded length of what was read).
    pub(crate) fn bytes_consumed(&self) -> usize {
        self.pos.div_ceil(8) as usize
    }
}

/// Appends an unsigned LEB128 varint.
pub(crate) fn put_varint(out: &mut Vec<u8>, mut value: u64) {
    loop {
        let byte = (value & 0x7F) as u8;
        value >>= 7;
        if value == 0 {
            out.push(byte);
            return;
        }
        out.push(byte | 0x80);
    }
}

/// A cursor over header bytes with typed, bounds-checked reads.
#[derive(Debug)]
pub(crate) struct ByteCursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> ByteCursor<'a> {
    pub(crate) fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, pos: 0 }
    }

    pub(crate) fn take(&mut self, n: usize) -> Result<&'a [u8], ChainError> {
        let end = self.pos.checked_add(n).ok_or(ChainError::Truncated)?;
        let slice = self.bytes.get(self.pos..end).ok_or(ChainError::Truncated)?;
        self.pos = end;
        Ok(slice)
    }

    pub(crate) fn u8(&mut self) -> Result<u8, ChainError> {
        Ok(self.take(1)?[0])
    }

    pub(crate) fn f32(&mut self) -> Result<f32, ChainError> {
        let b = self.take(4)?;
        Ok(f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    }

    pub(crate) fn f64(&mut self) -> Result<f64, ChainError> {
        let b = self.take(8)?;
        let mut a = [0u8; 8];
        a.copy_from_slice(b);
        Ok(f64::from_le_bytes(a))
    }

    pub(crate) fn varint(&mut self) -> Result<u64, ChainError> {
        let mut value = 0u64;
        for i in 0..10 {
            let byte = self.u8()?;
            let bits = u64::from(byte & 0x7F);
            if i == 9 && bits > 1 {
                return Err(ChainError::Malformed("varint overflows 64 bits"));
            }
            value |= bits << (7 * i);
            if byte & 0x80 == 0 {
                return Ok(value);
            }
        }
        Err(ChainError::Malformed("varint longer than 10 bytes"))
    }

    /// The bytes not yet read.
    pub(crate) fn rest(&self) -> &'a [u8] {
        &self.bytes[self.pos..]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn bits_round_trip(items in proptest::collection::vec((any::<u64>(), 0u32..=64), 0..200)) {
            let mut w = BitWriter::new();
            for &(v, n) in &items {
                w.write(v, n);
            }
            let total = w.bit_len();
            let bytes = w.finish();
            prop_assert_eq!(bytes.len() as u64, total.div_ceil(8));
            let mut r = BitReader::new(&bytes);
            for &(v, n) in &items {
                let mask = if n == 64 { u64::MAX } else { (1u64 << n) - 1 };
                prop_assert_eq!(r.read(n), v & mask);
            }
            prop_assert!(!r.overrun());
        }

        #[test]
        fn varint_round_trip(values in proptest::collection::vec(any::<u64>(), 0..50)) {
            let mut out = Vec::new();
            for &v in &values {
                put_varint(&mut out, v);
            }
            let mut c = ByteCursor::new(&out);
            for &v in &values {
                prop_assert_eq!(c.varint().unwrap(), v);
            }
            prop_assert!(c.rest().is_empty());
        }
    }

    #[test]
    fn reading_past_the_end_flags_overrun() {
        let mut r = BitReader::new(&[0xFF]);
        assert_eq!(r.read(4), 0xF);
        assert!(!r.overrun());
        assert_eq!(r.read(8), 0xF0);
        assert!(r.overrun());
    }

    #[test]
    fn overlong_varint_is_rejected() {
        let bytes = [0xFF; 11];
        assert!(ByteCursor::new(&bytes).varint().is_err());
    }
}
