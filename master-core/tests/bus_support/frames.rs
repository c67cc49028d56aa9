//! Recognisable test frames: a sequence number inside a well-formed EtherCAT frame.

/// Offset of the sequence number: right after the Ethernet and EtherCAT headers.
const SEQ_OFFSET: usize = 16;

/// The Ethernet minimum without FCS; test frames are padded to it like real ones.
pub const MIN_FRAME_LEN: usize = 60;

/// A broadcast EtherCAT frame of `len` bytes (at least 20) carrying `seq`, the rest of the
/// payload a pattern derived from `seq` so that any misplaced byte shows.
pub fn test_frame(seq: u32, len: usize) -> Vec<u8> {
    assert!(
        len >= SEQ_OFFSET + 4,
        "a test frame needs room for its sequence number"
    );
    let mut frame = vec![0u8; len];
    frame[0..6].copy_from_slice(&[0xff; 6]);
    frame[6..12].copy_from_slice(&[0x02, 0x00, 0x00, 0x00, 0x00, 0x01]);
    frame[12..14].copy_from_slice(&[0x88, 0xa4]);
    // EtherCAT header: type 1 (datagrams), length = the rest of the frame.
    let ecat_len = u16::try_from(len - 16).expect("test frames are short") & 0x07ff;
    frame[14..16].copy_from_slice(&(0x1000 | ecat_len).to_le_bytes());
    frame[SEQ_OFFSET..SEQ_OFFSET + 4].copy_from_slice(&seq.to_le_bytes());
    for (i, byte) in frame.iter_mut().enumerate().skip(SEQ_OFFSET + 4) {
        *byte = (seq as usize).wrapping_mul(31).wrapping_add(i) as u8;
    }
    frame
}

/// The sequence number of a frame made by [`test_frame`].
pub fn seq_of(frame: &[u8]) -> u32 {
    let bytes: [u8; 4] = frame[SEQ_OFFSET..SEQ_OFFSET + 4]
        .try_into()
        .expect("four bytes");
    u32::from_le_bytes(bytes)
}
