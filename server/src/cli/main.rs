//! `ecat`: ecatd's command-line client over gRPC, with the commands, arguments and output
//! columns of IgH's `ethercat` tool so that scripts port. Human output by default, `--json`
//! for scripts. Slaves are selected as in IgH (`-p 3`, `-a 0x777`, `-p 0x777:2`) or by any
//! name of the common syntax (`-p station:1004`, `-p alias:0x777+2`).
//!
//! Files: `session` (the connection), `select` (slave selection), `parse` (argument
//! forms), `out` (printing), `failure` (the classes of failure and their exit status),
//! `master_index` (IgH's `-m`), `abbrev` (abbreviated commands), `progress` (transfer progress bars), one file per command group
//! under `commands/`, `gateway` (the mailbox gateway command), `diag_message` (decoding the
//! diagnosis history for `diag`), `esi` (the ESI fragment `xml` prints).

mod abbrev;
mod client;
mod commands;
mod config;
mod diag_message;
mod eoe;
mod esi;
mod failure;
mod gateway;
mod master_index;
mod out;
mod parse;
mod progress;
mod select;
mod session;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

use crate::failure::{Class, Failure};
use crate::out::Out;
use crate::session::Session;

/// Command line.
#[derive(Debug, Parser)]
#[command(
    name = "ecat",
    version,
    about = "Command-line client of ecatd (gRPC)",
    infer_subcommands = true,
    after_help = EXIT_STATUS
)]
pub struct Cli {
    /// ecatd's gRPC address: `host:port`, `http://host:port` or `https://host:port`.
    // Its own id: a global option shares its id with the commands' arguments, and
    // `reg_read` has an argument `address` (the register's).
    #[arg(
        id = "ecatd_address",
        long = "address",
        global = true,
        env = "ECAT_ADDRESS",
        default_value = "http://127.0.0.1:50051"
    )]
    pub address: String,
    /// Bearer token.
    #[arg(long, global = true, env = "ECAT_TOKEN")]
    pub token: Option<String>,
    /// Connect over TLS, trusting this CA certificate (PEM); an `http://` address is then
    /// taken as `https://`.
    #[arg(long, global = true, env = "ECAT_TLS_CA", value_name = "FILE")]
    pub tls_ca: Option<std::path::PathBuf>,
    /// JSON output; a failure is then one JSON object on standard error.
    #[arg(long, global = true)]
    pub json: bool,
    /// IgH's master index: ecatd runs one master, index 0 (`0`, `-` or a list such as
    /// `0,0-0`); another index is refused (run `ecat --address` of that master's ecatd).
    #[arg(
        id = "master_index",
        short = 'm',
        long = "master",
        global = true,
        value_name = "INDICES",
        default_value = "0",
        value_parser = master_index::parse
    )]
    pub master: u32,
    /// What to do.
    #[command(subcommand)]
    pub command: Command,
}

/// The exit status table `ecat --help` ends with (`failure::Class`; a unit test keeps
/// them equal).
const EXIT_STATUS: &str = "Exit status: 0 success, 1 other, 2 usage, 3 not_found, \
4 refused (by the slave: SDO/SoE/FoE abort, AL state), 5 timeout, 6 unreachable, \
7 permission. With --json a failure is a JSON object on standard error: class, exit_code, \
message, and when known status, grpc_code, reason, abort_code (\"0x06020000\").";

/// A command: its arguments, and what running it prints.
pub(crate) trait Run {
    /// Runs the command (connecting through `session` if it needs ecatd).
    async fn run(self, session: &mut Session) -> Result<Out, Failure>;
}

/// Declares the command set: each line is a doc comment and `Name(path::Args)`, the name
/// becoming the command in snake_case (`FoeRead` is `foe_read`). A new command group is one
/// `mod` line above and one line here.
macro_rules! command_set {
    ($( $(#[$meta:meta])* $variant:ident($args:ty), )*) => {
        /// The commands (IgH `ethercat`'s names).
        #[derive(Debug, Subcommand)]
        #[command(rename_all = "snake_case")]
        #[allow(clippy::large_enum_variant)]
        pub enum Command {
            $( $(#[$meta])* $variant($args), )*
        }

        async fn dispatch(command: Command, session: &mut Session) -> Result<Out, Failure> {
            match command {
                $( Command::$variant(args) => args.run(session).await, )*
            }
        }
    };
}

command_set! {
    /// List the slaves: position, alias:relpos, state, error flag, name (IgH's columns);
    /// `-v` for identity, ESC, ports, DC, mailboxes.
    Slaves(commands::slaves::Slaves),
    /// Show the master: link, slaves, ecatd's version.
    Master(commands::master::MasterCmd),
    /// Scan the segment again.
    Rescan(commands::master::Rescan),
    /// Print the client's and the server's versions.
    Version(commands::master::Version),
    /// Request an AL state (INIT, PREOP, BOOT, SAFEOP, OP) for the selected slaves (all
    /// when none is selected).
    States(commands::states::States),
    /// Show the events ecatd kept, with their times (`--since 10m`, `--kind`, `-p`, `-n`);
    /// `-f` then follows the new ones.
    Events(commands::events::Events),
    /// SDO upload: print an object entry (`0x... decimal` for integers).
    Upload(commands::coe::Upload),
    /// SDO download: write an object entry.
    Download(commands::coe::Download),
    /// List the CoE dictionary (SDO Information) with its entries.
    Sdos(commands::coe::Sdos),
    /// Show each slave's SyncManagers, the PDOs assigned to them and their entries, with
    /// their names (IgH's `pdos`; every slave when none is selected).
    Pdos(commands::pd::Pdos),
    /// Print each slave's PDO assignment as the C structures of IgH's application
    /// interface (`ec_pdo_entry_info_t`, `ec_pdo_info_t`, `ec_sync_info_t`).
    Cstruct(commands::cstruct::Cstruct),
    /// Show the process data's named entries with their live values (slave, index:sub,
    /// name, type, direction, value, forced by); `--watch [INTERVAL]` follows them,
    /// `--force -p SLAVE INDEX SUB VALUE [--override]` forces an output, `--release -p
    /// SLAVE [INDEX SUB]` releases it (or every forced output), `--forced` lists them.
    Pd(commands::pd::Pd),
    /// Read an SoE IDN (`S-0-0011`, `P-0-0100` or a number).
    SoeRead(commands::soe::SoeRead),
    /// Write an SoE IDN.
    SoeWrite(commands::soe::SoeWrite),
    /// Read a file over FoE (raw bytes to standard output, or to `-o FILE`).
    FoeRead(commands::foe::FoeRead),
    /// Write a file over FoE (IgH's order: the local file, `-o` for the name on the slave).
    FoeWrite(commands::foe::FoeWrite),
    /// Send a VoE message and print the answer.
    Voe(commands::voe::Voe),
    /// Show or set the EoE IP parameters (set when any option is given).
    Ip(commands::ip::Ip),
    /// Set the EoE address filter: the MACs whose frames the slave passes to its device.
    EoeFilter(commands::eoe_filter::EoeFilter),
    /// Set the station alias.
    Alias(commands::registers::Alias),
    /// Read ESC registers.
    RegRead(commands::registers::RegRead),
    /// Write ESC registers.
    RegWrite(commands::registers::RegWrite),
    /// Write ESC registers and print what was there before, in one FPRW datagram.
    RegRdwr(commands::registers::RegRdwr),
    /// Show the ESC error counters (0x0300-0x0313) of every slave.
    Crc(commands::registers::Crc),
    /// Read the SII image (raw bytes to standard output, or to `-o FILE`).
    SiiRead(commands::sii::SiiRead),
    /// Write an SII image file (checksum checked; `--force` writes it as it is).
    SiiWrite(commands::sii::SiiWrite),
    /// Capture the live bus to pcapng: `ecat pcap -c 1000 -w bus.pcapng`.
    Pcap(commands::pcap::Pcap),
    /// Write the process image (every domain's bytes) to standard output; `--hex` to read.
    Data(commands::domains::Data),
    /// List the domains (slave groups): logical address, size, working counter, slaves;
    /// `-v` for their entries and data.
    Domains(commands::domains::Domains),
    /// Show or set ecatd's runtime log filter (IgH's levels 0-2, or a filter).
    Debug(commands::debug::Debug),
    /// Show a slave's diagnosis history (0x10F3) decoded.
    Diag(commands::diag::Diag),
    /// Print an ESI fragment (EtherCATInfo XML) generated from each slave's SII.
    Xml(commands::xml::Xml),
    /// Print the topology as a Graphviz graph (`ecat graph | dot -Tsvg`).
    Graph(commands::graph::Graph),
    /// The mailbox gateway's state and statistics; `start` or `stop` it.
    Gateway(gateway::Gateway),
    /// The slave configurations (IgH's `config`: alias:position, vendor/product, attached
    /// slave, state; `-v` details); `--toml` the whole configuration ecatd runs with.
    Config(config::Config),
    /// The EoE interfaces: name, MAC, state, slave and counters.
    Eoe(eoe::Eoe),
    /// Print a shell completion script (bash, zsh, fish, elvish, powershell).
    #[command(alias = "completion")]
    Completions(commands::docs::Completion),
    /// Print the man page of ecat or of one command (roff); `--out DIR` writes every page.
    Man(commands::docs::Man),
}

fn main() -> ExitCode {
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    let json = args
        .iter()
        .take_while(|arg| *arg != "--")
        .any(|arg| arg == "--json");
    let cli = match Cli::try_parse_from(&args) {
        Ok(cli) => cli,
        Err(err) => return refused_command_line(abbrev::ambiguity(err), json),
    };
    let runtime = match tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
    {
        Ok(runtime) => runtime,
        Err(err) => return report(&Failure::other(err.to_string()), json),
    };
    let mut session = Session::new(cli.address, cli.token, cli.tls_ca);
    session.set_json(json);
    match runtime
        .block_on(dispatch(cli.command, &mut session))
        .and_then(|out| out.print(json))
    {
        Ok(()) => ExitCode::SUCCESS,
        Err(failure) => report(&failure, json),
    }
}

/// A command line clap did not take: `--help` and `--version` print and succeed; an error
/// is a usage failure (clap's status 2), as JSON with `--json`.
fn refused_command_line(err: clap::Error, json: bool) -> ExitCode {
    if !err.use_stderr() || !json {
        // Prints help to standard output, an error to standard error.
        let _ = err.print();
        return ExitCode::from(u8::try_from(err.exit_code()).unwrap_or(2));
    }
    let text = err.render().to_string();
    let message = text.trim_end().trim_start_matches("error: ");
    report(&Failure::new(Class::Usage, message), json)
}

/// Prints a failure to standard error (a JSON object with `--json`) and gives its exit
/// status.
fn report(failure: &Failure, json: bool) -> ExitCode {
    if json {
        eprintln!("{}", failure.json());
    } else {
        eprintln!("ecat: {failure}");
    }
    ExitCode::from(failure.class.exit_code())
}

#[cfg(test)]
mod tests {
    use clap::CommandFactory;

    #[test]
    fn the_command_line_is_consistent() {
        super::Cli::command().debug_assert();
    }

    #[test]
    fn the_global_address_is_not_a_register_address() {
        use clap::Parser;
        let cli = super::Cli::try_parse_from([
            "ecat",
            "reg_read",
            "-p",
            "1",
            "0x0130",
            "2",
            "--address",
            "ecatd:1",
        ])
        .expect("parses");
        assert_eq!(cli.address, "ecatd:1");
        match cli.command {
            super::Command::RegRead(read) => assert_eq!(read.address, "0x0130"),
            other => panic!("not reg_read: {other:?}"),
        }
    }

    #[test]
    fn help_lists_every_exit_status() {
        for class in super::Class::ALL {
            let entry = format!("{} {}", class.exit_code(), class.name());
            assert!(super::EXIT_STATUS.contains(&entry), "{entry} missing");
        }
    }
}
