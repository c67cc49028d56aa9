//! Every operation of the core that needs the write role, declared once: its name (the
//! `operation` of its audit line, and of the refusal a read token gets) and the marker type
//! an adapter names to be admitted for it ([`super::admission`]).
//!
//! An operation is here because it changes the segment or ecatd (a state, a register, a
//! value, a file, the gateway, the log filter) or because what it reads is a secret (a
//! capture carries every mailbox transfer, FoE passwords included). Reads that need no more
//! than a read token are not listed: the adapters' authentication is all they need.

/// Declares the operations and one marker type per operation.
macro_rules! operations {
    ($($(#[doc = $doc:literal])* $variant:ident => $name:literal,)*) => {
        /// An operation that needs the write role; see the [module documentation](self).
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
        pub enum Operation {
            $($(#[doc = $doc])* $variant,)*
        }

        impl Operation {
            /// Every operation, in declaration order.
            pub const ALL: &'static [Operation] = &[$(Operation::$variant,)*];

            /// The operation's name (`coe_download`).
            pub fn name(self) -> &'static str {
                match self {
                    $(Operation::$variant => $name,)*
                }
            }
        }

        /// One type per [`Operation`], for an adapter whose admission is a type (a REST
        /// handler's `Admit<op::CoeDownload>` argument).
        pub mod op {
            $(
                $(#[doc = $doc])*
                #[derive(Debug, Clone, Copy)]
                pub struct $variant;

                impl super::Marker for $variant {
                    const OPERATION: super::Operation = super::Operation::$variant;
                }
            )*
        }
    };
}

/// A marker type of [`op`]: the operation it stands for.
pub trait Marker {
    /// The operation.
    const OPERATION: Operation;
}

operations! {
    /// Moves a slave to an AL state.
    RequestState => "request_state",
    /// Scans the segment again (every slave back through INIT).
    Rescan => "rescan",
    /// Writes ESC registers.
    WriteRegister => "write_register",
    /// Writes ESC registers and reads what they held (FPRW).
    ReadWriteRegister => "read_write_register",
    /// Reads registers whose read has an effect on the slave (a mailbox SyncManager's
    /// buffer: the read empties it). The core decides from the address.
    ReadRegisterWithEffect => "read_register",
    /// Writes SII words.
    WriteSii => "write_sii",
    /// Writes the station alias (SII word 4 and the register).
    SetAlias => "set_alias",
    /// CoE SDO download.
    CoeDownload => "coe_download",
    /// SoE write.
    SoeWrite => "soe_write",
    /// FoE write (a file into the slave).
    FoeWrite => "foe_write",
    /// A VoE message: it may do anything its vendor defined.
    Voe => "voe",
    /// EoE Set IP Parameter.
    EoeSetIp => "eoe_set_ip",
    /// EoE Set address filter: which frames the slave passes to its device.
    EoeSetAddressFilter => "eoe_set_address_filter",
    /// Forces a process-data output over what the control program commits.
    ForceOutput => "force_output",
    /// Releases a forced output.
    ReleaseOutput => "release_output",
    /// Starts the mailbox gateway.
    StartGateway => "start_gateway",
    /// Stops the mailbox gateway.
    StopGateway => "stop_gateway",
    /// Changes what ecatd logs (ecatd has no role above write).
    SetLogFilter => "set_log_filter",
    /// A live or rolling capture: its frames carry every mailbox transfer, FoE passwords
    /// included.
    Capture => "capture",
    /// Raises a CoE emergency on a simulated slave (`--simulate` only).
    SimEmergency => "sim_emergency",
    /// Cuts a cable of the simulated ring, kills a slave on it or heals it (`--simulate`
    /// on a ring only).
    SimRing => "sim_ring",
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_are_unique_and_marked() {
        for (i, op) in Operation::ALL.iter().enumerate() {
            assert!(
                !Operation::ALL[..i].iter().any(|o| o.name() == op.name()),
                "{} twice",
                op.name()
            );
        }
        assert_eq!(
            <op::CoeDownload as Marker>::OPERATION.name(),
            "coe_download"
        );
    }
}
