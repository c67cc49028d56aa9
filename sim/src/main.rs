//! `ecat-sim`: runs an emulated EtherCAT segment on a network interface.

use std::process::ExitCode;

fn main() -> ExitCode {
    eprintln!(
        "ecat-sim: the slave emulation is not built yet (see the issue \"The slave simulator\"); \
         nothing to run"
    );
    ExitCode::from(2)
}
