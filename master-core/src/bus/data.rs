//! The bytes of one datagram, kept inline when small.

use core::fmt;
use core::ops::{Deref, DerefMut};

/// Data lengths up to this many bytes are stored inside the value, without allocation.
///
/// Register accesses, the bulk of acyclic traffic, are 1 to 8 bytes (an SII read is 8, a
/// SyncManager 8, two SyncManagers 16, AL status and code 6); 30 keeps the whole value at
/// 32 bytes.
pub const INLINE_LEN: usize = 30;

/// The data of a datagram: what is sent, and after the reply what came back.
///
/// A request's data is allocated (only when longer than [`INLINE_LEN`]) on the submitting
/// thread; the bus thread copies the returned bytes into the same storage and hands it back
/// in the response, so it never allocates itself.
#[derive(Clone)]
pub struct DatagramData(Storage);

#[derive(Clone)]
enum Storage {
    Inline { len: u8, bytes: [u8; INLINE_LEN] },
    Heap(Box<[u8]>),
}

impl DatagramData {
    /// `len` zero bytes: the data of a read request (slaves fill it in; a BRD ORs into it,
    /// so it must start as zeros).
    pub fn zeroed(len: usize) -> DatagramData {
        match u8::try_from(len) {
            Ok(short) if len <= INLINE_LEN => DatagramData(Storage::Inline {
                len: short,
                bytes: [0; INLINE_LEN],
            }),
            _ => DatagramData(Storage::Heap(vec![0; len].into_boxed_slice())),
        }
    }

    /// A copy of `bytes`.
    pub fn from_slice(bytes: &[u8]) -> DatagramData {
        let mut data = DatagramData::zeroed(bytes.len());
        data.copy_from_slice(bytes);
        data
    }

    /// The bytes.
    pub fn as_slice(&self) -> &[u8] {
        match &self.0 {
            Storage::Inline { len, bytes } => &bytes[..usize::from(*len)],
            Storage::Heap(bytes) => bytes,
        }
    }

    /// The bytes, to change in place.
    pub fn as_mut_slice(&mut self) -> &mut [u8] {
        match &mut self.0 {
            Storage::Inline { len, bytes } => &mut bytes[..usize::from(*len)],
            Storage::Heap(bytes) => bytes,
        }
    }

    /// The bytes as a vector (allocates).
    pub fn to_vec(&self) -> Vec<u8> {
        self.as_slice().to_vec()
    }

    /// True if the bytes live inside the value rather than on the heap.
    pub fn is_inline(&self) -> bool {
        matches!(self.0, Storage::Inline { .. })
    }
}

impl Default for DatagramData {
    /// No bytes.
    fn default() -> DatagramData {
        DatagramData::zeroed(0)
    }
}

impl Deref for DatagramData {
    type Target = [u8];

    fn deref(&self) -> &[u8] {
        self.as_slice()
    }
}

impl DerefMut for DatagramData {
    fn deref_mut(&mut self) -> &mut [u8] {
        self.as_mut_slice()
    }
}

impl AsRef<[u8]> for DatagramData {
    fn as_ref(&self) -> &[u8] {
        self.as_slice()
    }
}

impl From<&[u8]> for DatagramData {
    fn from(bytes: &[u8]) -> DatagramData {
        DatagramData::from_slice(bytes)
    }
}

impl<const N: usize> From<[u8; N]> for DatagramData {
    fn from(bytes: [u8; N]) -> DatagramData {
        DatagramData::from_slice(&bytes)
    }
}

impl From<Vec<u8>> for DatagramData {
    /// Takes the vector's allocation when the data is too long to keep inline.
    fn from(bytes: Vec<u8>) -> DatagramData {
        if bytes.len() <= INLINE_LEN {
            DatagramData::from_slice(&bytes)
        } else {
            DatagramData(Storage::Heap(bytes.into_boxed_slice()))
        }
    }
}

impl PartialEq for DatagramData {
    fn eq(&self, other: &DatagramData) -> bool {
        self.as_slice() == other.as_slice()
    }
}

impl Eq for DatagramData {}

impl PartialEq<[u8]> for DatagramData {
    fn eq(&self, other: &[u8]) -> bool {
        self.as_slice() == other
    }
}

impl fmt::Debug for DatagramData {
    /// Hex bytes, like a capture: `[01 10 00 00]`.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("[")?;
        for (i, byte) in self.as_slice().iter().enumerate() {
            if i > 0 {
                f.write_str(" ")?;
            }
            write!(f, "{byte:02x}")?;
        }
        f.write_str("]")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn short_data_stays_inline_and_long_data_goes_to_the_heap() {
        let short = DatagramData::zeroed(INLINE_LEN);
        assert!(short.is_inline());
        assert_eq!(short.len(), INLINE_LEN);
        assert!(short.iter().all(|&b| b == 0));
        let long = DatagramData::zeroed(INLINE_LEN + 1);
        assert!(!long.is_inline());
        assert_eq!(long.len(), INLINE_LEN + 1);
        assert_eq!(size_of::<DatagramData>(), 32);
    }

    #[test]
    fn conversions_keep_the_bytes() {
        let bytes: Vec<u8> = (0..100).collect();
        assert_eq!(DatagramData::from(bytes.clone()).as_slice(), &bytes[..]);
        assert_eq!(DatagramData::from(&bytes[..3]).as_slice(), &[0, 1, 2]);
        assert_eq!(DatagramData::from([7u8, 8]).to_vec(), vec![7, 8]);
        let mut data = DatagramData::from([1u8, 2, 3]);
        data[1] = 9;
        assert_eq!(data, DatagramData::from([1u8, 9, 3]));
        assert_eq!(format!("{data:?}"), "[01 09 03]");
        assert!(DatagramData::zeroed(0).is_empty());
    }
}
