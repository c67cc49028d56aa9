//! The `ecat-sim` front end: a simulated segment behind a network interface.
//!
//! - [`changes`]: changes to the segment (power cycles, cut cables, dead slaves) queued for
//!   the frame loop;
//! - [`describe`]: the lines that say what is emulated, printed at start;
//! - [`control`]: `--control`, the terminals' physical side on the standard streams;
//! - [`counter`]: frames in and out, and the rate line printed about once per second;
//! - [`eoe_tap`]: `--eoe-tap`, an EoE slave's Ethernet side bridged to a TAP interface;
//! - [`ring`]: `--backup-iface`, the loop that answers frames on both ports of a ring;
//! - [`serve`]: the loop that answers frames (receive, run through the segment, send back).

pub mod changes;
pub mod control;
pub mod counter;
pub mod describe;
pub mod eoe_tap;
pub mod ring;
pub mod serve;

/// Frames the front end's tests send.
#[cfg(test)]
pub mod test_frames {
    use ecat_link::MAX_FRAME_LEN;
    use ecat_wire::command::{Command, DatagramAddress};
    use ecat_wire::datagram::{DatagramRepr, FrameBuilder};

    /// A frame with one BRD of the AL status (2 bytes): every slave that processes it counts.
    pub fn brd_frame() -> Vec<u8> {
        let mut buf = vec![0u8; MAX_FRAME_LEN];
        let mut builder = FrameBuilder::new(&mut buf).unwrap();
        builder
            .push(&DatagramRepr::request(
                Command::Brd,
                0,
                DatagramAddress::broadcast(0x0130),
                &[0, 0],
            ))
            .unwrap();
        let len = builder.finish([0, 0, 0, 0, 0, 1]).unwrap();
        buf.truncate(len);
        buf
    }
}
