//! Copying bit fields between byte buffers (process data is packed bit by bit, LSB
//! first, ETG.1000.6, spec-notes §coe.ca, §coe.pdo).

/// Copies `len` bits from `src` at bit `from` to `dst` at bit `to`. Returns false, and
/// changes nothing, if either range runs past its buffer.
pub(crate) fn copy_bits(src: &[u8], from: usize, dst: &mut [u8], to: usize, len: usize) -> bool {
    let fits =
        |buf_len: usize, at: usize| at.checked_add(len).is_some_and(|end| end <= buf_len * 8);
    if !fits(src.len(), from) || !fits(dst.len(), to) {
        return false;
    }
    if from.is_multiple_of(8) && to.is_multiple_of(8) && len.is_multiple_of(8) {
        // Byte-aligned entries (most of them): a plain copy.
        let (f, t, n) = (from / 8, to / 8, len / 8);
        dst[t..t + n].copy_from_slice(&src[f..f + n]);
        return true;
    }
    for i in 0..len {
        let (s, d) = (from + i, to + i);
        let on = src[s / 8] & (1 << (s % 8)) != 0;
        if on {
            dst[d / 8] |= 1 << (d % 8);
        } else {
            dst[d / 8] &= !(1 << (d % 8));
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bits_land_lsb_first_and_out_of_range_changes_nothing() {
        let mut dst = [0u8; 2];
        assert!(copy_bits(&[0b1], 0, &mut dst, 3, 1));
        assert_eq!(dst, [0b1000, 0]);
        assert!(copy_bits(&[0xAB, 0xCD], 0, &mut dst, 0, 16));
        assert_eq!(dst, [0xAB, 0xCD]);
        // 4 bits straddling a byte boundary.
        let mut dst = [0u8; 2];
        assert!(copy_bits(&[0b1111], 0, &mut dst, 6, 4));
        assert_eq!(dst, [0b1100_0000, 0b11]);
        assert!(!copy_bits(&[0xFF], 0, &mut dst, 12, 8));
        assert_eq!(dst, [0b1100_0000, 0b11]);
    }
}
