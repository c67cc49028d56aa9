//! The capture writer of the cycle benchmark's capturing row: what ecatd's capture task
//! does with each frame (one pcapng Enhanced Packet Block), into any writer.

use std::borrow::Cow;
use std::io::Write;

use master_core::link::CapturedFrame;
use pcap_file::DataLink;
use pcap_file::pcapng::PcapNgWriter;
use pcap_file::pcapng::blocks::enhanced_packet::EnhancedPacketBlock;
use pcap_file::pcapng::blocks::interface_description::{
    InterfaceDescriptionBlock, InterfaceDescriptionOption,
};

/// A pcapng section with one Ethernet interface at nanosecond resolution.
pub struct PcapNg<W: Write> {
    writer: PcapNgWriter<W>,
    /// Frames written.
    pub frames: u64,
}

impl<W: Write> PcapNg<W> {
    /// Starts the section.
    pub fn new(out: W) -> PcapNg<W> {
        let mut writer = PcapNgWriter::new(out).expect("pcapng header");
        writer
            .write_pcapng_block(InterfaceDescriptionBlock {
                linktype: DataLink::ETHERNET,
                snaplen: 0,
                options: vec![InterfaceDescriptionOption::IfTsResol(9)],
            })
            .expect("pcapng interface");
        PcapNg { writer, frames: 0 }
    }

    /// Appends one frame.
    pub fn write(&mut self, frame: &CapturedFrame) {
        self.writer
            .write_pcapng_block(EnhancedPacketBlock {
                interface_id: 0,
                timestamp: frame.at,
                original_len: frame.frame.len() as u32,
                data: Cow::Borrowed(&frame.frame),
                options: Vec::new(),
            })
            .expect("pcapng packet");
        self.frames += 1;
    }
}
