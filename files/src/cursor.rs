//! A bounds-checked little-endian reader over bytes held in memory: the one cursor the binary
//! formats (sessions, device recordings) decode with. Every read checks the bytes left before
//! it takes any, so a short or hostile file is refused where it falls short, naming the
//! offset, and never read past. Sizes read from a file are the caller's to bound before they
//! reach [`ByteCursor::take`]; the cursor itself allocates nothing.

/// A read that needed more bytes than were left.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("needs {needed} bytes at byte {offset}, {available} left")]
pub struct ShortRead {
    /// Where the read began, bytes from the start of the cursor's slice.
    pub offset: usize,
    /// Bytes the read needed.
    pub needed: usize,
    /// Bytes that were left.
    pub available: usize,
}

/// A position in a byte slice, advanced by each successful read and left where it was by a
/// failed one.
#[derive(Clone, Debug)]
pub struct ByteCursor<'a> {
    bytes: &'a [u8],
    at: usize,
}

impl<'a> ByteCursor<'a> {
    /// A cursor at the start of `bytes`.
    #[must_use]
    pub fn new(bytes: &'a [u8]) -> Self {
        Self { bytes, at: 0 }
    }

    /// The whole slice the cursor reads.
    #[must_use]
    pub fn bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// Bytes read so far (the offset of the next read).
    #[must_use]
    pub fn at(&self) -> usize {
        self.at
    }

    /// Bytes left to read.
    #[must_use]
    pub fn remaining(&self) -> usize {
        self.bytes.len() - self.at
    }

    /// Moves back to `at` (an offset already read past, so that an error can point at the
    /// start of what it refuses); an offset ahead of the cursor leaves it where it is.
    pub fn rewind_to(&mut self, at: usize) {
        self.at = self.at.min(at);
    }

    /// The next `n` bytes.
    ///
    /// # Errors
    /// [`ShortRead`] when fewer than `n` are left; the cursor does not move.
    pub fn take(&mut self, n: usize) -> Result<&'a [u8], ShortRead> {
        if self.remaining() < n {
            return Err(ShortRead {
                offset: self.at,
                needed: n,
                available: self.remaining(),
            });
        }
        let taken = &self.bytes[self.at..self.at + n];
        self.at += n;
        Ok(taken)
    }

    /// The next `N` bytes as an array.
    ///
    /// # Errors
    /// As [`ByteCursor::take`].
    pub fn array<const N: usize>(&mut self) -> Result<[u8; N], ShortRead> {
        let taken = self.take(N)?;
        Ok(taken
            .try_into()
            .unwrap_or_else(|_| unreachable!("take gave N bytes")))
    }

    /// The next byte.
    ///
    /// # Errors
    /// As [`ByteCursor::take`].
    pub fn u8(&mut self) -> Result<u8, ShortRead> {
        Ok(self.array::<1>()?[0])
    }

    /// The next little-endian `u16`.
    ///
    /// # Errors
    /// As [`ByteCursor::take`].
    pub fn u16(&mut self) -> Result<u16, ShortRead> {
        self.array().map(u16::from_le_bytes)
    }

    /// The next little-endian `u32`.
    ///
    /// # Errors
    /// As [`ByteCursor::take`].
    pub fn u32(&mut self) -> Result<u32, ShortRead> {
        self.array().map(u32::from_le_bytes)
    }

    /// The next little-endian `u64`.
    ///
    /// # Errors
    /// As [`ByteCursor::take`].
    pub fn u64(&mut self) -> Result<u64, ShortRead> {
        self.array().map(u64::from_le_bytes)
    }

    /// The next little-endian `f32`.
    ///
    /// # Errors
    /// As [`ByteCursor::take`].
    pub fn f32(&mut self) -> Result<f32, ShortRead> {
        self.array().map(f32::from_le_bytes)
    }

    /// The next little-endian `f64`.
    ///
    /// # Errors
    /// As [`ByteCursor::take`].
    pub fn f64(&mut self) -> Result<f64, ShortRead> {
        self.array().map(f64::from_le_bytes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_little_endian_values_in_order_and_refuses_a_short_read_without_moving() {
        let mut bytes = vec![7u8];
        bytes.extend(0x0102u16.to_le_bytes());
        bytes.extend(0x0304_0506u32.to_le_bytes());
        bytes.extend(0x0708_090a_0b0c_0d0eu64.to_le_bytes());
        bytes.extend(1.5f32.to_le_bytes());
        bytes.extend((-2.25f64).to_le_bytes());
        bytes.extend([1, 2]);
        let mut c = ByteCursor::new(&bytes);
        assert_eq!(c.u8(), Ok(7));
        assert_eq!(c.u16(), Ok(0x0102));
        assert_eq!(c.u32(), Ok(0x0304_0506));
        assert_eq!(c.u64(), Ok(0x0708_090a_0b0c_0d0e));
        assert_eq!(c.f32(), Ok(1.5));
        assert_eq!(c.f64(), Ok(-2.25));
        let at = c.at();
        assert_eq!(
            c.u32(),
            Err(ShortRead {
                offset: at,
                needed: 4,
                available: 2
            })
        );
        assert_eq!(c.at(), at, "a failed read does not move the cursor");
        assert_eq!(c.take(2), Ok(&[1u8, 2][..]));
        assert_eq!(c.remaining(), 0);
        assert!(
            c.take(usize::MAX).is_err(),
            "a huge size is refused, not added"
        );
        c.rewind_to(1);
        assert_eq!(c.at(), 1);
        c.rewind_to(100);
        assert_eq!(c.at(), 1, "rewinding never moves ahead");
    }
}
