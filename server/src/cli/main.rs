//! `ecat`: ecatd's command-line client over gRPC, with the subcommands of IgH's `ethercat`
//! tool. Human output by default, `--json` for scripts. Slaves are named as everywhere:
//! `3` (position), `#1004` (station), `@0x777` (alias).

mod client;
mod commands;
mod eoe;
mod gateway;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

/// Command line.
#[derive(Debug, Parser)]
#[command(name = "ecat", version, about = "Command-line client of ecatd (gRPC)")]
pub struct Cli {
    /// ecatd's gRPC address.
    #[arg(long, env = "ECAT_ADDRESS", default_value = "http://127.0.0.1:50051")]
    pub address: String,
    /// Bearer token.
    #[arg(long, env = "ECAT_TOKEN")]
    pub token: Option<String>,
    /// Connect over TLS, trusting this CA certificate (PEM); an `http://` address is then
    /// taken as `https://`.
    #[arg(long, env = "ECAT_TLS_CA", value_name = "FILE")]
    pub tls_ca: Option<std::path::PathBuf>,
    /// JSON output.
    #[arg(long, global = true)]
    pub json: bool,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The subcommands.
#[derive(Debug, Subcommand)]
#[allow(clippy::large_enum_variant)]
pub enum Command {
    /// List the slaves.
    Slaves,
    /// Request an AL state (INIT, PREOP, BOOT, SAFEOP, OP) for one slave or all.
    States {
        /// The slave; all slaves when absent.
        #[arg(short = 'p', long)]
        slave: Option<String>,
        /// The state.
        state: String,
    },
    /// SDO upload.
    Upload {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// Object index.
        index: String,
        /// Subindex.
        subindex: String,
        /// Value type: auto (from the slave's SDO Information), u8 … u64, i8 … i64, f32,
        /// f64, bool, string, hex.
        #[arg(long = "type", default_value = "auto")]
        ty: String,
        /// Complete access.
        #[arg(long)]
        complete: bool,
    },
    /// SDO download.
    Download {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// Object index.
        index: String,
        /// Subindex.
        subindex: String,
        /// The value, as `--type` says (hex bytes with `--complete`).
        value: String,
        /// Value type: auto (from the slave's SDO Information) or a type name.
        #[arg(long = "type", default_value = "auto")]
        ty: String,
        /// Complete access.
        #[arg(long)]
        complete: bool,
    },
    /// List the CoE dictionary (SDO Information).
    Sdos {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
    },
    /// Read an SoE IDN.
    #[command(name = "soe_read")]
    SoeRead {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// Drive number.
        #[arg(long, default_value = "0")]
        drive: u8,
        /// IDN number (`0x8064` for P-0-0100).
        idn: String,
        /// Value type.
        #[arg(long = "type", default_value = "hex")]
        ty: String,
    },
    /// Write an SoE IDN.
    #[command(name = "soe_write")]
    SoeWrite {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// Drive number.
        #[arg(long, default_value = "0")]
        drive: u8,
        /// IDN number.
        idn: String,
        /// The value.
        value: String,
        /// Value type.
        #[arg(long = "type", default_value = "hex")]
        ty: String,
    },
    /// Read a file over FoE.
    #[command(name = "foe_read")]
    FoeRead {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// File name on the slave.
        name: String,
        /// Where to write it (standard output when absent).
        #[arg(short = 'o', long)]
        output: Option<std::path::PathBuf>,
        /// Password.
        #[arg(long, default_value = "0")]
        password: u32,
    },
    /// Write a file over FoE.
    #[command(name = "foe_write")]
    FoeWrite {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// File name on the slave.
        name: String,
        /// Local file.
        file: std::path::PathBuf,
        /// Password.
        #[arg(long, default_value = "0")]
        password: u32,
    },
    /// Send a VoE message and print the answer.
    Voe {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// Vendor id.
        vendor_id: String,
        /// Vendor type.
        vendor_type: String,
        /// Payload, hex.
        data: String,
    },
    /// Show or set the EoE IP parameters (set when any option is given).
    Ip {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// IP address.
        #[arg(long)]
        ip: Option<String>,
        /// Subnet mask.
        #[arg(long)]
        mask: Option<String>,
        /// Default gateway.
        #[arg(long)]
        gateway: Option<String>,
        /// DNS server.
        #[arg(long)]
        dns: Option<String>,
        /// DNS name.
        #[arg(long)]
        name: Option<String>,
        /// MAC address.
        #[arg(long)]
        mac: Option<String>,
    },
    /// Set the station alias.
    Alias {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// The alias.
        alias: String,
    },
    /// Read ESC registers.
    #[command(name = "reg_read")]
    RegRead {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// Register address.
        address: String,
        /// Bytes (default 1).
        #[arg(default_value = "1")]
        length: String,
    },
    /// Write ESC registers.
    #[command(name = "reg_write")]
    RegWrite {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// Register address.
        address: String,
        /// Data, hex.
        data: String,
    },
    /// Read the SII image.
    #[command(name = "sii_read")]
    SiiRead {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// Where to write it (hex dump to standard output when absent).
        #[arg(short = 'o', long)]
        output: Option<std::path::PathBuf>,
    },
    /// Write SII words.
    #[command(name = "sii_write")]
    SiiWrite {
        /// The slave.
        #[arg(short = 'p', long, default_value = "0")]
        slave: String,
        /// First word address.
        word: String,
        /// Data, hex (little-endian words).
        data: String,
    },
    /// The mailbox gateway's state and statistics; `start` or `stop` it.
    Gateway {
        /// What to do (nothing: show the state).
        #[command(subcommand)]
        action: Option<gateway::Action>,
    },
    /// The EoE interfaces: name, MAC, state, slave and counters.
    Eoe,
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let runtime = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(runtime) => runtime,
        Err(err) => {
            eprintln!("ecat: {err}");
            return ExitCode::from(1);
        }
    };
    match runtime.block_on(commands::run(cli)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(err) => {
            eprintln!("ecat: {err}");
            ExitCode::from(1)
        }
    }
}
