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
