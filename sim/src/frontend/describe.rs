//! What the simulator emulates, one line per slave, from the topology and the built segment.

use std::fmt::Write as _;

use sim::segment::Segment;
use sim::topology::{Application, Protocol, Topology};

/// One line per slave: position, name, identity, mailbox sizes, protocols, the process
/// data the device exchanges with its current assignment and where its inputs are wired.
pub fn slave_lines(topology: &Topology, segment: &Segment) -> Vec<String> {
    topology
        .slaves
        .iter()
        .enumerate()
        .map(|(position, spec)| {
            let mut line = format!(
                "slave {position}: {:?} vendor 0x{:08X} product 0x{:08X} revision 0x{:08X}",
                spec.name, spec.vendor_id, spec.product_code, spec.revision
            );
            match spec.mailbox {
                Some(m) => {
                    let _ = write!(line, ", mailbox {}/{} bytes", m.rx_size, m.tx_size);
                    let names: Vec<&str> = spec.protocols.iter().map(protocol_name).collect();
                    let _ = write!(line, ", protocols {}", names.join(" "));
                }
                None => line.push_str(", no mailbox"),
            }
            if let Some(slave) = segment.slave(position) {
                let sizes = slave.device().process_data_sizes();
                let _ = write!(
                    line,
                    ", process data {} bytes out / {} bytes in",
                    sizes.outputs, sizes.inputs
                );
            }
            if let Application::DigitalInputs {
                wired_to: Some(to), ..
            } = spec.application
            {
                let _ = write!(line, ", inputs wired to slave {to}'s outputs");
            }
            line
        })
        .collect()
}

/// The protocol's usual short name.
fn protocol_name(protocol: &Protocol) -> &'static str {
    match protocol {
        Protocol::Coe => "CoE",
        Protocol::Eoe => "EoE",
        Protocol::Foe => "FoE",
        Protocol::Soe => "SoE",
        Protocol::Voe => "VoE",
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use sim::topology::build;

    #[test]
    fn one_line_per_slave_with_identity_mailbox_and_process_data() {
        let topology = Topology::default_segment();
        let segment = build(&topology).unwrap();
        let lines = slave_lines(&topology, &segment);
        assert_eq!(lines.len(), topology.slaves.len());
        let drive = &topology.slaves[0];
        assert!(lines[0].starts_with(&format!("slave 0: {:?}", drive.name)));
        assert!(lines[0].contains(&format!("product 0x{:08X}", drive.product_code)));
        assert!(lines[0].contains("protocols CoE SoE FoE VoE EoE"));
        // The drive maps 0x6040 + 0x607A out and 0x6041 + 0x6064 in: 6 bytes each way.
        assert!(lines[0].ends_with("process data 6 bytes out / 6 bytes in"));
        assert!(lines[1].contains("no mailbox"));
        assert!(lines[1].ends_with("1 bytes out / 0 bytes in"));
        assert!(lines[2].ends_with("0 bytes out / 1 bytes in, inputs wired to slave 1's outputs"));
    }
}
