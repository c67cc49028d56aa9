//! ecatd's configuration: a TOML file, then `ECATD_*` environment variables, then flags
//! (flags win). `--print-config` shows the result, `--check-config` checks it and exits.
//!
//! The segment's configuration has files of its own: `[bus]` (`bus`), `[[slave]]`
//! (`slaves`), `[[group]]` (`groups`), durations (`duration`), and the ENI import that
//! becomes the same `[bus] cycle` and `[[slave]]` entries (`eni`); so do the servers'
//! connection limits (`[limits]`, `limits`).

pub mod app;
pub mod bus;
pub mod capture;
pub mod duration;
pub mod eni;
pub mod eoe;
pub mod events;
pub mod groups;
pub mod limits;
pub mod slaves;
pub mod tokens;
pub mod watch;

use std::net::{IpAddr, SocketAddr};
use std::path::PathBuf;
use std::str::FromStr;

use clap::Parser;
use serde::{Deserialize, Serialize};

use master_core::gateway::{AllowedNet, ClientNet, GatewayConfig, GatewayRole};

use tokens::Token;

/// Command-line flags; each also reads its `ECATD_*` environment variable.
#[derive(Debug, Parser)]
#[command(
    name = "ecatd",
    version,
    about = "EtherCAT master with gRPC, REST and metrics"
)]
pub struct Args {
    /// Configuration file (TOML).
    #[arg(long, env = "ECATD_CONFIG", value_name = "FILE")]
    pub config: Option<PathBuf>,
    /// Run on the in-process simulated segment (the built-in five slaves, or a topology file).
    #[arg(long, env = "ECATD_SIMULATE", value_name = "TOPOLOGY", num_args = 0..=1,
          default_missing_value = "", conflicts_with = "iface")]
    pub simulate: Option<String>,
    /// Run on this network interface (raw socket; needs CAP_NET_RAW).
    #[arg(long, env = "ECATD_IFACE", value_name = "IFNAME")]
    pub iface: Option<String>,
    /// Cable redundancy: the interface the far end of the ring comes back into (`[bus]
    /// backup_iface`, docs/redundancy.md); only with `--iface`.
    #[arg(long, env = "ECATD_BACKUP_IFACE", value_name = "IFNAME")]
    pub backup_iface: Option<String>,
    /// Wire the simulated segment as a ring into two ports of the master (cable
    /// redundancy, `[segment.simulate] ring = true`); only with `--simulate`.
    #[arg(long, env = "ECATD_RING")]
    pub ring: bool,
    /// gRPC listen address.
    #[arg(long, env = "ECATD_GRPC_LISTEN", value_name = "ADDR")]
    pub grpc_listen: Option<SocketAddr>,
    /// HTTP listen address (REST, metrics, health).
    #[arg(long, env = "ECATD_HTTP_LISTEN", value_name = "ADDR")]
    pub http_listen: Option<SocketAddr>,
    /// ETG.8200 mailbox gateway listen address (UDP): `IP` (port from the master number) or
    /// `IP:PORT`.
    #[arg(long, env = "ECATD_GATEWAY_LISTEN", value_name = "ADDR")]
    pub gateway_listen: Option<GatewayListen>,
    /// The master number of the gateway (1-based): without a port in the listen address,
    /// it serves on 34980 + (number - 1).
    #[arg(long, env = "ECATD_GATEWAY_MASTER_NUMBER", value_name = "N",
          value_parser = clap::value_parser!(u16).range(1..), conflicts_with = "no_gateway")]
    pub gateway_master_number: Option<u16>,
    /// Do not run the mailbox gateway.
    #[arg(long, env = "ECATD_NO_GATEWAY", conflicts_with = "gateway_listen")]
    pub no_gateway: bool,
    /// Log format: `human` or `json`.
    #[arg(long, env = "ECATD_LOG_FORMAT", value_name = "FORMAT")]
    pub log_format: Option<LogFormat>,
    /// Log filter (tracing `EnvFilter` syntax, e.g. `info,server=debug`).
    #[arg(long, env = "ECATD_LOG", value_name = "FILTER")]
    pub log: Option<String>,
    /// Allow listening on a non-loopback address without tokens.
    #[arg(long, env = "ECATD_INSECURE")]
    pub insecure: bool,
    /// TLS certificate chain (PEM) for gRPC and HTTP; needs --tls-key.
    #[arg(
        long,
        env = "ECATD_TLS_CERT",
        value_name = "FILE",
        requires = "tls_key"
    )]
    pub tls_cert: Option<PathBuf>,
    /// TLS private key (PEM); needs --tls-cert.
    #[arg(
        long,
        env = "ECATD_TLS_KEY",
        value_name = "FILE",
        requires = "tls_cert"
    )]
    pub tls_key: Option<PathBuf>,
    /// The state every slave is brought to on SIGINT/SIGTERM: init (default) or safeop.
    #[arg(long, env = "ECATD_SAFE_STATE", value_name = "STATE")]
    pub safe_state: Option<SafeState>,
    /// Host names (or addresses) the HTTP API answers to besides loopback and the
    /// listener's own address; repeat for several (DNS rebinding protection).
    #[arg(
        long = "allowed-host",
        env = "ECATD_ALLOWED_HOSTS",
        value_name = "HOST",
        value_delimiter = ','
    )]
    pub allowed_hosts: Vec<String>,
    /// Audit log file (JSON lines, appended); default: standard error.
    #[arg(long, env = "ECATD_AUDIT_LOG", value_name = "FILE")]
    pub audit_log: Option<PathBuf>,
    /// `/metrics` needs a token (read role) when tokens are configured.
    #[arg(long, env = "ECATD_METRICS_TOKEN")]
    pub metrics_token: bool,
    /// An ENI file (ETG.2100 EtherCAT Network Information) describing the segment: its
    /// cycle time and slaves, instead of `[[slave]]` entries.
    #[arg(long, env = "ECATD_ENI", value_name = "FILE")]
    pub eni: Option<PathBuf>,
    /// The Unix socket control programs attach to (`[app] socket`; docs/application.md).
    #[arg(long, env = "ECATD_APP_SOCKET", value_name = "PATH")]
    pub app_socket: Option<PathBuf>,
    /// Print the effective configuration as TOML and exit.
    #[arg(long)]
    pub print_config: bool,
    /// Check the configuration (and the ENI file), say what is wrong, and exit: 0 when
    /// it is good, 2 when not.
    #[arg(long, conflicts_with = "print_config")]
    pub check_config: bool,
    /// Print a shell completion script for ecatd (bash, zsh, fish, elvish, powershell) and
    /// exit.
    #[arg(long, value_name = "SHELL")]
    pub completions: Option<clap_complete::Shell>,
    /// Print ecatd's man page (roff) and exit.
    #[arg(long, conflicts_with = "completions")]
    pub man: bool,
}

/// The state ecatd leaves the slaves in when it stops.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum, Default)]
#[serde(rename_all = "lowercase")]
pub enum SafeState {
    /// INIT: no mailbox, no process data (ETG.1000.6 §6.4).
    #[default]
    Init,
    /// SAFEOP: inputs still exchanged, outputs in their safe state.
    Safeop,
}

impl SafeState {
    /// The AL state.
    pub fn al_state(self) -> master_core::wire::register::AlState {
        match self {
            SafeState::Init => master_core::wire::register::AlState::Init,
            SafeState::Safeop => master_core::wire::register::AlState::SafeOp,
        }
    }
}

/// Log output format.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, clap::ValueEnum, Default)]
#[serde(rename_all = "lowercase")]
pub enum LogFormat {
    /// Human-readable lines.
    #[default]
    Human,
    /// One JSON object per line.
    Json,
}

/// Where the segment is.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Segment {
    /// The in-process simulator, with a topology file or the built-in one.
    Simulate {
        /// Topology file (TOML); absent: the built-in five-slave segment.
        topology: Option<PathBuf>,
        /// Wire the segment as a ring into the master's two ports (cable redundancy), as a
        /// topology's own `ring = true` does; `--ring`.
        #[serde(default, skip_serializing_if = "std::ops::Not::not")]
        ring: bool,
    },
    /// A network interface.
    Iface {
        /// Interface name.
        name: String,
    },
}

/// Where the gateway listens: an IP address and, optionally, a port (`127.0.0.1` or
/// `127.0.0.1:34980`; port 0: any free port). Without a port the gateway takes ETG.8200's
/// 34980 + (master number - 1).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GatewayListen {
    /// Address to bind.
    pub ip: IpAddr,
    /// Port; `None`: from the master number.
    pub port: Option<u16>,
}

impl FromStr for GatewayListen {
    type Err = String;

    fn from_str(text: &str) -> Result<GatewayListen, String> {
        if let Ok(addr) = text.parse::<SocketAddr>() {
            return Ok(GatewayListen {
                ip: addr.ip(),
                port: Some(addr.port()),
            });
        }
        let bare = text.trim_start_matches('[').trim_end_matches(']');
        bare.parse::<IpAddr>()
            .map(|ip| GatewayListen { ip, port: None })
            .map_err(|_| format!("{text:?} is neither IP nor IP:PORT"))
    }
}

impl std::fmt::Display for GatewayListen {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.port {
            Some(port) => SocketAddr::new(self.ip, port).fmt(f),
            None => self.ip.fmt(f),
        }
    }
}

impl Serialize for GatewayListen {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for GatewayListen {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        String::deserialize(deserializer)?
            .parse()
            .map_err(serde::de::Error::custom)
    }
}

/// One client network of the gateway's allowlist: `"10.0.0.0/8"` (role `write`) or
/// `{ net = "10.0.0.0/8", role = "read" }`.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum GatewayAllow {
    /// A network whose clients may write.
    Net(String),
    /// A network and its role (`read` or `write`).
    WithRole {
        /// The network (CIDR).
        net: String,
        /// `read` or `write`.
        role: String,
    },
}

impl GatewayAllow {
    /// The network and role, checked.
    pub fn allowed(&self) -> Result<AllowedNet, String> {
        let (net, role) = match self {
            GatewayAllow::Net(net) => (net, GatewayRole::Write),
            GatewayAllow::WithRole { net, role } => (
                net,
                role.parse::<GatewayRole>()
                    .map_err(|err| format!("gateway allow {net:?}: {err}"))?,
            ),
        };
        let net = net
            .parse::<ClientNet>()
            .map_err(|err| format!("gateway allow {net:?}: {err}"))?;
        Ok(AllowedNet::new(net, role))
    }
}

/// The mailbox gateway's settings (`[gateway]`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GatewaySettings {
    /// Whether ecatd runs the gateway (`false`: as `--no-gateway`).
    pub enabled: bool,
    /// UDP listen address: `IP` or `IP:PORT`; default `127.0.0.1` with the port from
    /// `master_number` (34980 for master 1). A taken port falls back to a free one, which
    /// the log, the API and the metrics report.
    pub listen: GatewayListen,
    /// This master's number (1-based) when several masters run on one host.
    pub master_number: u16,
    /// Client networks allowed to send requests, each with a role (`"10.0.0.0/8"`: write;
    /// `{ net = "10.0.0.0/8", role = "read" }`); empty: loopback with write. A non-loopback
    /// network with write needs `insecure`.
    pub allow: Vec<GatewayAllow>,
    /// Strict mode: no error replies from the gateway itself (ETG.8200 permits silence).
    pub strict: bool,
    /// Milliseconds after its answer during which a repeated UDP request (same bytes,
    /// counter 1-7) is answered from the stored reply instead of running again; 0: never.
    pub retry_window_ms: u64,
    /// UDP receive workers, each a thread with its own socket on the gateway's port (1 to
    /// [`MAX_GATEWAY_WORKERS`]); default: one fewer than the cores available, 1 to 4
    /// ([`master_core::gateway::default_workers`]). Every client stays with one worker, so
    /// its requests keep their order. Not used while `on_bus_thread` holds.
    pub workers: Option<usize>,
    /// Serve UDP from the bus thread where the link allows it (default true); false: from
    /// the `workers` ([`GatewayConfig::on_bus_thread`]).
    pub on_bus_thread: bool,
}

/// Most receive workers `[gateway] workers` may ask for.
pub const MAX_GATEWAY_WORKERS: usize = 64;

impl Default for GatewaySettings {
    fn default() -> GatewaySettings {
        GatewaySettings {
            listen: GatewayListen {
                ip: IpAddr::from([127, 0, 0, 1]),
                port: None,
            },
            enabled: true,
            master_number: 1,
            allow: Vec::new(),
            strict: false,
            retry_window_ms: 1000,
            workers: None,
            on_bus_thread: true,
        }
    }
}

impl GatewaySettings {
    /// The library's configuration for these settings (the rest at its defaults).
    pub fn gateway_config(&self) -> Result<GatewayConfig, String> {
        if self.master_number == 0 {
            return Err("gateway master_number must be 1 or more".into());
        }
        let allow = if self.allow.is_empty() {
            AllowedNet::all(ClientNet::loopback(), GatewayRole::Write)
        } else {
            self.allow
                .iter()
                .map(GatewayAllow::allowed)
                .collect::<Result<Vec<_>, _>>()?
        };
        let defaults = GatewayConfig::default();
        let workers = match self.workers {
            None => defaults.workers,
            Some(n) if (1..=MAX_GATEWAY_WORKERS).contains(&n) => n,
            Some(n) => {
                return Err(format!(
                    "gateway workers must be 1 to {MAX_GATEWAY_WORKERS}, not {n}"
                ));
            }
        };
        Ok(GatewayConfig {
            bind: self.listen.ip,
            port: self.listen.port,
            master_number: self.master_number,
            allow,
            strict: self.strict,
            retry_window: std::time::Duration::from_millis(self.retry_window_ms),
            workers,
            on_bus_thread: self.on_bus_thread,
            ..defaults
        })
    }

    /// Refuses clients outside loopback with the write role unless `insecure`: the gateway
    /// has no tokens, so such a network could change the segment unauthenticated.
    fn check(&self, insecure: bool) -> Result<(), String> {
        let config = self.gateway_config()?;
        if insecure {
            return Ok(());
        }
        match config
            .allow
            .iter()
            .find(|a| a.role == GatewayRole::Write && !a.net.is_loopback())
        {
            Some(open) => Err(format!(
                "refusing to let gateway clients of {} write without tokens; give that [gateway] allow entry role = \"read\" ({{ net = \"{}\", role = \"read\" }}), or pass --insecure",
                open.net, open.net
            )),
            None => Ok(()),
        }
    }
}

/// TLS for both APIs (`[tls]`): PEM files.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TlsSettings {
    /// Certificate chain, leaf first.
    pub cert: PathBuf,
    /// Private key (PKCS#8, PKCS#1 or SEC1).
    pub key: PathBuf,
}

/// What the bus and the master are started with, from `[bus]`, `[[slave]]` and
/// `[[group]]` (or the ENI).
#[derive(Debug, Clone)]
pub struct SegmentSetup {
    /// The bus.
    pub bus: master_core::bus::BusConfig,
    /// The master.
    pub master: master_core::master::MasterConfig,
    /// The CPU the bus thread is pinned to.
    pub cpu: Option<usize>,
    /// Expected identities, start-up commands, DC, watchdog.
    pub slaves: master_core::master::SlaveConfigs,
    /// PDO assignments, by slave.
    pub pdos: Vec<(
        master_core::master::SlaveAddress,
        Vec<master_core::master::PdoAssignment>,
    )>,
    /// Slave groups.
    pub groups: Vec<master_core::master::SlaveGroup>,
    /// The ring's second port (`[bus] backup_iface`): with it the bus runs on a ring.
    pub backup_iface: Option<String>,
}

/// Most threads `api_threads` may ask for.
pub const MAX_API_THREADS: usize = 64;

/// The effective configuration.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Config {
    /// The segment; absent: none configured (ecatd refuses to start).
    pub segment: Option<Segment>,
    /// gRPC listen address.
    pub grpc_listen: SocketAddr,
    /// HTTP listen address.
    pub http_listen: SocketAddr,
    /// The ETG.8200 mailbox gateway (UDP); absent: no gateway.
    pub gateway: Option<GatewaySettings>,
    /// Log format.
    pub log_format: LogFormat,
    /// Log filter.
    pub log: String,
    /// Allow non-loopback listening without tokens.
    pub insecure: bool,
    /// API tokens (`[[tokens]]` tables: name, token, role = "read" | "write").
    pub tokens: Vec<Token>,
    /// TLS for gRPC and HTTP; absent: plain TCP.
    pub tls: Option<TlsSettings>,
    /// Watched values (`[[watch]]` tables), exported as gauges.
    pub watch: Vec<watch::WatchSpec>,
    /// The state the slaves are left in on SIGINT/SIGTERM.
    pub safe_state: SafeState,
    /// The whole shutdown's time limit, signal to exit, in milliseconds.
    pub shutdown_timeout_ms: u64,
    /// Threads of the runtime that serves gRPC and HTTP (1 to [`MAX_API_THREADS`]). The
    /// bus, the mailbox timer and the gateway have threads of their own. One keeps a
    /// request on one thread from socket to answer: with more, each answer from the bus
    /// thread wakes a second, idle worker as well, which cost REST and gRPC about 25 µs
    /// per request (`docs/performance.md`). More serve many concurrent clients on more
    /// cores.
    pub api_threads: usize,
    /// Host names the HTTP API answers to besides loopback and the listener's address.
    pub allowed_hosts: Vec<String>,
    /// Where the audit lines (one JSON object per line, whatever the log level) go: a file
    /// appended to; absent: standard error.
    pub audit_log: Option<PathBuf>,
    /// Whether `/metrics` needs a token (read role) when tokens are configured.
    pub metrics_token: bool,
    /// The bus: cycle, scheduling, timeouts, target state, watchdog, mismatch policy.
    pub bus: bus::BusSettings,
    /// An ENI file to take the cycle and the slaves from (instead of `[[slave]]`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub eni: Option<PathBuf>,
    /// The expected slaves and what each gets at bring-up.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub slave: Vec<slaves::SlaveEntry>,
    /// Slave groups with periods of their own.
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub group: Vec<groups::GroupEntry>,
    /// EoE interfaces (`[eoe]`, see [`eoe`]).
    pub eoe: eoe::EoeSettings,
    /// The rolling capture (`[capture]`).
    pub capture: capture::CaptureSettings,
    /// The event history and its journal (`[events]`).
    pub events: events::EventSettings,
    /// The application interface (`[app]`, docs/application.md).
    pub app: app::AppSettings,
    /// Connection limits of the HTTP and gRPC servers (`[limits]`).
    pub limits: limits::LimitSettings,
    /// The configuration file this came from (SIGHUP reloads its tokens).
    #[serde(skip)]
    pub file: Option<PathBuf>,
    /// The parts of the ENI file ecatd does not use (logged once at start).
    #[serde(skip)]
    pub eni_unused: Vec<String>,
}

impl Default for Config {
    fn default() -> Config {
        Config {
            segment: None,
            grpc_listen: SocketAddr::from(([127, 0, 0, 1], 50051)),
            http_listen: SocketAddr::from(([127, 0, 0, 1], 8080)),
            gateway: Some(GatewaySettings::default()),
            log_format: LogFormat::Human,
            log: "info".into(),
            insecure: false,
            tokens: Vec::new(),
            tls: None,
            watch: Vec::new(),
            safe_state: SafeState::Init,
            shutdown_timeout_ms: 5000,
            api_threads: 1,
            allowed_hosts: Vec::new(),
            audit_log: None,
            metrics_token: false,
            bus: bus::BusSettings::default(),
            eni: None,
            slave: Vec::new(),
            group: Vec::new(),
            eoe: Default::default(),
            capture: capture::CaptureSettings::default(),
            events: events::EventSettings::default(),
            app: app::AppSettings::default(),
            limits: limits::LimitSettings::default(),
            file: None,
            eni_unused: Vec::new(),
        }
    }
}

impl Config {
    /// The file's configuration (or the defaults) with the flags and environment on top.
    pub fn load(args: &Args) -> Result<Config, String> {
        let mut config = match &args.config {
            Some(path) => {
                let text = std::fs::read_to_string(path)
                    .map_err(|err| format!("cannot read {}: {err}", path.display()))?;
                toml::from_str(&text).map_err(|err| format!("{}: {err}", path.display()))?
            }
            None => Config::default(),
        };
        config.file = args.config.clone();
        if let Some(topology) = &args.simulate {
            config.segment = Some(Segment::Simulate {
                topology: (!topology.is_empty()).then(|| PathBuf::from(topology)),
                ring: false,
            });
        }
        if let Some(name) = &args.iface {
            config.segment = Some(Segment::Iface { name: name.clone() });
        }
        if let Some(backup) = &args.backup_iface {
            config.bus.backup_iface = Some(backup.clone());
        }
        if args.ring {
            match &mut config.segment {
                Some(Segment::Simulate { ring, .. }) => *ring = true,
                _ => {
                    return Err(
                        "--ring wires the simulated segment as a ring: it needs --simulate \
                         (a real ring's second port is --backup-iface IFNAME)"
                            .into(),
                    );
                }
            }
        }
        config.check_redundancy()?;
        if let Some(addr) = args.grpc_listen {
            config.grpc_listen = addr;
        }
        if let Some(addr) = args.http_listen {
            config.http_listen = addr;
        }
        if args.no_gateway {
            config.gateway = None;
        } else {
            if let Some(addr) = args.gateway_listen {
                config
                    .gateway
                    .get_or_insert_with(GatewaySettings::default)
                    .listen = addr;
            }
            if let Some(number) = args.gateway_master_number {
                config
                    .gateway
                    .get_or_insert_with(GatewaySettings::default)
                    .master_number = number;
            }
        }
        if let Some(format) = args.log_format {
            config.log_format = format;
        }
        if let Some(log) = &args.log {
            config.log = log.clone();
        }
        // `enabled = false` wins over a listen address given on the command line.
        if config.gateway.as_ref().is_some_and(|g| !g.enabled) {
            config.gateway = None;
        }
        config.insecure |= args.insecure;
        if let Some(state) = args.safe_state {
            config.safe_state = state;
        }
        config
            .allowed_hosts
            .extend(args.allowed_hosts.iter().cloned());
        if let (Some(cert), Some(key)) = (&args.tls_cert, &args.tls_key) {
            config.tls = Some(TlsSettings {
                cert: cert.clone(),
                key: key.clone(),
            });
        }
        if let Some(path) = &args.audit_log {
            config.audit_log = Some(path.clone());
        }
        config.metrics_token |= args.metrics_token;
        for token in &mut config.tokens {
            token.resolve()?;
        }
        if let Some(eni) = &args.eni {
            config.eni = Some(eni.clone());
        }
        if let Some(socket) = &args.app_socket {
            config.app.socket = Some(socket.clone());
        }
        config.import_eni()?;
        if !(1..=MAX_API_THREADS).contains(&config.api_threads) {
            return Err(format!(
                "api_threads must be 1 to {MAX_API_THREADS}, not {}",
                config.api_threads
            ));
        }
        let named = |err: String| match &config.file {
            Some(path) => format!("{}: {err}", path.display()),
            None => err,
        };
        config.segment_setup().map_err(named)?;
        Ok(config)
    }

    /// Refuses a backup interface that cannot be one: on the simulator (whose ring is
    /// `--ring`), without an interface segment, or the primary interface itself.
    fn check_redundancy(&self) -> Result<(), String> {
        let Some(backup) = &self.bus.backup_iface else {
            return Ok(());
        };
        match &self.segment {
            Some(Segment::Iface { name }) if name == backup => Err(format!(
                "[bus] backup_iface = {backup:?} is the primary interface itself: the ring's \
                 far end must come back into a second port (docs/redundancy.md)"
            )),
            Some(Segment::Iface { .. }) => Ok(()),
            Some(Segment::Simulate { .. }) => Err(format!(
                "--backup-iface / [bus] backup_iface = {backup:?} needs a segment on an \
                 interface (--iface); the simulator's ring is --ring or [segment.simulate] \
                 ring = true"
            )),
            None => Err(format!(
                "[bus] backup_iface = {backup:?} needs the primary interface (--iface IFNAME)"
            )),
        }
    }

    /// Takes the cycle and the slaves from the ENI file, if one is configured (a relative
    /// path in the configuration file is taken from the file's folder). ENI slaves are
    /// the exact network: unless `[bus] on_mismatch` says otherwise, a mismatch stops.
    fn import_eni(&mut self) -> Result<(), String> {
        let Some(path) = self.eni.clone() else {
            return Ok(());
        };
        if !self.slave.is_empty() {
            return Err(format!(
                "{}: give the slaves as [[slave]] entries or as an ENI file ({}), not both",
                self.file
                    .as_ref()
                    .map_or("the configuration".into(), |f| f.display().to_string()),
                path.display()
            ));
        }
        let path = match (&self.file, path.is_relative()) {
            (Some(file), true) => file.parent().map_or(path.clone(), |dir| dir.join(&path)),
            _ => path,
        };
        let imported = eni::load(&path)?;
        if let Some(cycle) = imported.cycle {
            self.bus.cycle = cycle;
        }
        self.bus.on_mismatch.get_or_insert(bus::OnMismatch::Stop);
        self.slave = imported.slaves;
        self.eni = Some(path);
        self.eni_unused = imported.unused;
        Ok(())
    }

    /// What the master gets from `[bus]`, `[[slave]]` and `[[group]]`, checked.
    pub fn segment_setup(&self) -> Result<SegmentSetup, String> {
        self.bus.check()?;
        self.capture.check()?;
        self.events.check()?;
        self.app.check()?;
        let mut slave_configs = Vec::new();
        let mut pdos = Vec::new();
        let mut addresses = Vec::new();
        for (i, entry) in self.slave.iter().enumerate() {
            let label = entry.label(i + 1);
            let setup = entry.setup().map_err(|err| format!("{label}: {err}"))?;
            let address = setup.config.address;
            if addresses.contains(&address) {
                return Err(format!(
                    "{label}: another [[slave]] entry names the same slave"
                ));
            }
            addresses.push(address);
            if let (Some(address), false) = (address, setup.pdos.is_empty()) {
                pdos.push((address, setup.pdos));
            }
            slave_configs.push(setup.config);
        }
        let groups = groups::groups(&self.group, self.bus.cycle)?;
        let watchdog = self
            .bus
            .watchdog
            .as_ref()
            .map(bus::WatchdogSettings::watchdog)
            .transpose()?;
        Ok(SegmentSetup {
            bus: self.bus.bus_config(),
            master: self.bus.master_config(),
            cpu: self.bus.cpu,
            slaves: master_core::master::SlaveConfigs {
                slaves: slave_configs,
                policy: self.bus.on_mismatch.unwrap_or_default().policy(),
                report_extra: self.bus.report_extra,
                watchdog,
            },
            pdos,
            groups,
            backup_iface: self.bus.backup_iface.clone(),
        })
    }

    /// The tokens of the configuration file `path` again, resolved and checked (SIGHUP):
    /// the rest of the file is not applied.
    pub fn reload_tokens(&self, path: &std::path::Path) -> Result<Vec<Token>, String> {
        let text = std::fs::read_to_string(path)
            .map_err(|err| format!("cannot read {}: {err}", path.display()))?;
        let file: Config =
            toml::from_str(&text).map_err(|err| format!("{}: {err}", path.display()))?;
        let mut tokens = file.tokens;
        for token in &mut tokens {
            token.resolve()?;
        }
        let reloaded = Config {
            tokens: tokens.clone(),
            ..self.clone()
        };
        reloaded.check()?;
        Ok(tokens)
    }

    /// Refuses a non-loopback listen address without tokens, and non-loopback gateway
    /// clients with the write role, unless `insecure`.
    pub fn check(&self) -> Result<(), String> {
        if let Some(gateway) = &self.gateway {
            gateway.check(self.insecure)?;
        }
        watch::check_all(&self.watch)?;
        self.limits.check()?;
        for token in &self.tokens {
            // `load` resolved them; a configuration built otherwise is checked here too.
            if token.token.chars().count() < tokens::MIN_SECRET_LEN {
                return Err(format!(
                    "token {:?} is empty or shorter than {} characters",
                    token.name,
                    tokens::MIN_SECRET_LEN
                ));
            }
        }
        if !self.tokens.is_empty() && self.tls.is_none() && !self.insecure {
            for addr in [self.grpc_listen, self.http_listen] {
                if !addr.ip().is_loopback() {
                    return Err(format!(
                        "refusing to send API tokens in clear text on {addr}; configure [tls] (or --tls-cert and --tls-key), listen on loopback, or pass --insecure"
                    ));
                }
            }
        }
        if self.tokens.is_empty() && !self.insecure {
            for addr in [self.grpc_listen, self.http_listen] {
                if !addr.ip().is_loopback() {
                    return Err(format!(
                        "refusing to listen on {addr} without API tokens; configure [[tokens]] or pass --insecure"
                    ));
                }
            }
        }
        Ok(())
    }

    /// The configuration as TOML, token secrets masked.
    pub fn to_toml(&self) -> String {
        let mut shown = self.clone();
        for token in &mut shown.tokens {
            // A secret from a file or the environment is shown by its source only.
            token.token = if token.secret_file.is_some() || token.secret_env.is_some() {
                String::new()
            } else {
                "***".into()
            };
        }
        // The slaves and cycle of an ENI are shown as entries: the text reads back as a
        // configuration of its own, without the ENI.
        let from_eni = shown.eni.take().map(|eni| {
            format!(
                "# [bus] cycle and [[slave]] entries from the ENI file {}\n",
                eni.display()
            )
        });
        let text = toml::to_string(&shown).unwrap_or_else(|err| format!("# cannot show: {err}\n"));
        from_eni.unwrap_or_default() + &text
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(list: &[&str]) -> Args {
        Args::try_parse_from(std::iter::once("ecatd").chain(list.iter().copied())).unwrap()
    }

    #[test]
    fn flags_win_over_the_file() {
        let dir = std::env::temp_dir().join(format!("ecatd-config-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("ecatd.toml");
        std::fs::write(
            &file,
            "grpc_listen = \"127.0.0.1:1\"\nhttp_listen = \"127.0.0.1:2\"\n[segment.iface]\nname = \"eth9\"\n",
        )
        .unwrap();
        let path = file.to_str().unwrap();
        let from_file = Config::load(&args(&["--config", path])).unwrap();
        assert_eq!(from_file.grpc_listen.port(), 1);
        assert_eq!(
            from_file.segment,
            Some(Segment::Iface {
                name: "eth9".into()
            })
        );
        let flagged = Config::load(&args(&[
            "--config",
            path,
            "--grpc-listen",
            "127.0.0.1:3",
            "--simulate",
        ]))
        .unwrap();
        assert_eq!(flagged.grpc_listen.port(), 3);
        assert_eq!(flagged.http_listen.port(), 2);
        assert_eq!(
            flagged.segment,
            Some(Segment::Simulate {
                topology: None,
                ring: false
            })
        );
        let round = toml::from_str::<Config>(&flagged.to_toml()).unwrap();
        assert_eq!(round.file, None, "where it came from is not configuration");
        assert_eq!(
            round,
            Config {
                file: None,
                ..flagged
            }
        );
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn defaults_are_loopback() {
        let config = Config::load(&args(&[])).unwrap();
        assert_eq!(config.grpc_listen.to_string(), "127.0.0.1:50051");
        assert_eq!(config.http_listen.to_string(), "127.0.0.1:8080");
    }

    #[test]
    fn non_loopback_needs_tokens_or_insecure() {
        let open = Config::load(&args(&["--http-listen", "0.0.0.0:8080"])).unwrap();
        assert!(open.check().is_err());
        let insecure =
            Config::load(&args(&["--http-listen", "0.0.0.0:8080", "--insecure"])).unwrap();
        assert!(insecure.check().is_ok());
        let mut tokened = open.clone();
        tokened.tokens.push(Token {
            name: "a".into(),
            token: "s".repeat(16),
            secret_file: None,
            secret_env: None,
            role: tokens::Role::Read,
        });
        let err = tokened.check().unwrap_err();
        assert!(
            err.contains("0.0.0.0:8080") && err.contains("[tls]") && err.contains("--insecure"),
            "tokens without TLS off loopback: {err}"
        );
        tokened.tls = Some(TlsSettings {
            cert: "c.pem".into(),
            key: "k.pem".into(),
        });
        assert!(tokened.check().is_ok());
        assert!(!tokened.to_toml().contains(&"s".repeat(16)));
        let clear = Config {
            tls: None,
            insecure: true,
            ..tokened
        };
        assert!(clear.check().is_ok(), "--insecure allows clear text");
    }

    #[test]
    fn gateway_port_follows_the_master_number_unless_given() {
        let default = Config::load(&args(&[])).unwrap().gateway.unwrap();
        assert_eq!(default.gateway_config().unwrap().wanted_port(), 34980);
        let second = Config::load(&args(&["--gateway-master-number", "2"]))
            .unwrap()
            .gateway
            .unwrap();
        assert_eq!(second.listen.to_string(), "127.0.0.1");
        assert_eq!(second.gateway_config().unwrap().wanted_port(), 34981);
        let fixed = Config::load(&args(&[
            "--gateway-master-number",
            "2",
            "--gateway-listen",
            "127.0.0.1:4000",
        ]))
        .unwrap()
        .gateway
        .unwrap();
        assert_eq!(fixed.gateway_config().unwrap().wanted_port(), 4000);
        let file: Config =
            toml::from_str("[gateway]\nlisten = \"0.0.0.0\"\nmaster_number = 3\n").unwrap();
        let file = file.gateway.unwrap();
        assert_eq!(file.gateway_config().unwrap().wanted_port(), 34982);
        assert!(Args::try_parse_from(["ecatd", "--gateway-master-number", "0"]).is_err());
        assert!("300.0.0.1".parse::<GatewayListen>().is_err());
        let off: Config = toml::from_str("[gateway]\nenabled = false\n").unwrap();
        assert!(!off.gateway.unwrap().enabled);
    }

    #[test]
    fn gateway_workers_come_from_the_file_within_bounds() {
        let workers = |text: &str| {
            let file: Config = toml::from_str(text).unwrap();
            file.gateway.unwrap().gateway_config().map(|c| c.workers)
        };
        assert_eq!(
            workers("[gateway]\n"),
            Ok(GatewayConfig::default().workers),
            "the library's default"
        );
        assert_eq!(workers("[gateway]\nworkers = 1\n"), Ok(1));
        assert_eq!(workers("[gateway]\nworkers = 64\n"), Ok(64));
        for bad in [0, 65] {
            let err = workers(&format!("[gateway]\nworkers = {bad}\n")).unwrap_err();
            assert!(err.contains("gateway workers must be 1 to 64"), "{err}");
            let file: Config = toml::from_str(&format!("[gateway]\nworkers = {bad}\n")).unwrap();
            assert!(file.check().is_err(), "refused at start-up too");
        }
    }

    #[test]
    fn gateway_roles_come_from_the_file_and_open_writers_need_insecure() {
        let file: Config = toml::from_str(
            "[gateway]\nallow = [\"127.0.0.0/8\", { net = \"10.0.0.0/8\", role = \"read\" }]\nretry_window_ms = 250\n",
        )
        .unwrap();
        let config = file.gateway.as_ref().unwrap().gateway_config().unwrap();
        assert_eq!(
            config.role_of("127.0.0.1".parse().unwrap()),
            Some(GatewayRole::Write)
        );
        assert_eq!(
            config.role_of("10.1.2.3".parse().unwrap()),
            Some(GatewayRole::Read)
        );
        assert_eq!(config.role_of("192.168.0.1".parse().unwrap()), None);
        assert_eq!(config.retry_window, std::time::Duration::from_millis(250));
        assert!(
            file.check().is_ok(),
            "read clients outside loopback are fine"
        );
        let open: Config = toml::from_str("[gateway]\nallow = [\"10.0.0.0/8\"]\n").unwrap();
        let err = open.check().unwrap_err();
        assert!(
            err.contains("10.0.0.0/8")
                && err.contains("role = \"read\"")
                && err.contains("--insecure"),
            "{err}"
        );
        let insecure = Config {
            insecure: true,
            ..open
        };
        assert!(insecure.check().is_ok());
        let bad: Config =
            toml::from_str("[gateway]\nallow = [{ net = \"10.0.0.0/8\", role = \"admin\" }]\n")
                .unwrap();
        assert!(bad.check().unwrap_err().contains("admin"));
    }

    fn token_config(dir: &std::path::Path, body: &str) -> Result<Config, String> {
        let file = dir.join("ecatd.toml");
        std::fs::write(&file, body).unwrap();
        Config::load(&args(&["--config", file.to_str().unwrap()]))
    }

    #[test]
    fn short_or_empty_tokens_are_refused_by_name() {
        let dir = std::env::temp_dir().join(format!("ecatd-tokens-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        for (secret, what) in [("", "empty"), ("fifteen-chars-x", "too short")] {
            let err = token_config(
                &dir,
                &format!("[[tokens]]\nname = \"ops\"\ntoken = \"{secret}\"\nrole = \"read\"\n"),
            )
            .unwrap_err();
            assert!(err.contains("\"ops\"") && err.contains(what), "{err}");
            assert!(
                secret.is_empty() || !err.contains(secret),
                "secret shown: {err}"
            );
        }
        let ok = token_config(
            &dir,
            "[[tokens]]\nname = \"ops\"\ntoken = \"sixteen-chars-xx\"\nrole = \"read\"\n",
        )
        .unwrap();
        assert!(ok.check().is_ok());
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn secrets_come_from_a_file_or_the_environment() {
        let dir = std::env::temp_dir().join(format!("ecatd-secrets-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let secret = dir.join("secret");
        std::fs::write(&secret, "from-a-file-0123456789\n").unwrap();
        let var = format!("ECATD_TEST_SECRET_{}", std::process::id());
        // SAFETY: this test alone uses this variable; no other thread reads it.
        unsafe { std::env::set_var(&var, "from-the-environment-0123") };
        let config = token_config(
            &dir,
            &format!(
                "[[tokens]]\nname = \"f\"\nsecret_file = {:?}\nrole = \"read\"\n\n[[tokens]]\nname = \"e\"\nsecret_env = \"{var}\"\nrole = \"write\"\n",
                secret.to_str().unwrap()
            ),
        )
        .unwrap();
        assert_eq!(config.tokens[0].token, "from-a-file-0123456789");
        assert_eq!(config.tokens[1].token, "from-the-environment-0123");
        let shown = config.to_toml();
        assert!(
            !shown.contains("from-a-file") && !shown.contains("from-the-env"),
            "{shown}"
        );
        assert!(shown.contains(&var), "{shown}");
        let missing = token_config(
            &dir,
            "[[tokens]]\nname = \"gone\"\nsecret_env = \"ECATD_NO_SUCH_VARIABLE_X\"\nrole = \"read\"\n",
        )
        .unwrap_err();
        assert!(
            missing.contains("\"gone\"") && missing.contains("ECATD_NO_SUCH_VARIABLE_X"),
            "{missing}"
        );
        let both = token_config(
            &dir,
            &format!("[[tokens]]\nname = \"two\"\ntoken = \"sixteen-chars-xx\"\nsecret_env = \"{var}\"\nrole = \"read\"\n"),
        )
        .unwrap_err();
        assert!(both.contains("only one"), "{both}");
        std::fs::remove_dir_all(dir).unwrap();
    }

    #[test]
    fn limits_come_from_their_section_and_are_checked_at_start() {
        let file: Config =
            toml::from_str("[limits]\nheader_read_timeout = \"1s\"\nmax_connections = 500\n")
                .unwrap();
        assert_eq!(
            file.limits.header_read_timeout,
            std::time::Duration::from_secs(1)
        );
        assert_eq!(file.limits.max_connections, 500);
        assert_eq!(file.limits.max_connections_per_peer, 64, "the default");
        assert!(file.check().is_ok());
        assert_eq!(Config::default().limits, limits::LimitSettings::default());
        let bad: Config = toml::from_str("[limits]\nmax_connections = 0\n").unwrap();
        assert!(bad.check().unwrap_err().contains("max_connections"));
        // Below the per-address default: the message says which to change.
        let small: Config = toml::from_str("[limits]\nmax_connections = 50\n").unwrap();
        assert!(
            small
                .check()
                .unwrap_err()
                .contains("max_connections_per_peer = 64 must be 1 to max_connections (50)")
        );
    }

    #[test]
    fn unknown_keys_are_refused() {
        assert!(toml::from_str::<Config>("grpc_lisen = \"127.0.0.1:1\"").is_err());
    }

    fn try_args(list: &[&str]) -> Result<Config, String> {
        Config::load(&args(list))
    }

    #[test]
    fn the_backup_interface_comes_from_the_flag_or_the_file_and_needs_an_interface() {
        let flagged = try_args(&["--iface", "eth0", "--backup-iface", "eth1"]).unwrap();
        assert_eq!(flagged.bus.backup_iface.as_deref(), Some("eth1"));
        let filed: Config =
            toml::from_str("[segment.iface]\nname = \"eth0\"\n[bus]\nbackup_iface = \"eth1\"\n")
                .unwrap();
        assert_eq!(filed.bus.backup_iface.as_deref(), Some("eth1"));
        filed.check_redundancy().unwrap();
        assert!(
            filed.to_toml().contains("backup_iface = \"eth1\""),
            "--print-config shows it"
        );

        let simulated = try_args(&["--simulate", "--backup-iface", "eth1"]).unwrap_err();
        assert!(
            simulated.contains("needs a segment on an interface") && simulated.contains("--ring"),
            "{simulated}"
        );
        let itself = try_args(&["--iface", "eth0", "--backup-iface", "eth0"]).unwrap_err();
        assert!(
            itself.contains("is the primary interface itself"),
            "{itself}"
        );
        let alone = try_args(&["--backup-iface", "eth1"]).unwrap_err();
        assert!(alone.contains("needs the primary interface"), "{alone}");
    }

    #[test]
    fn the_simulated_ring_comes_from_the_flag_or_the_file_and_needs_the_simulator() {
        let flagged = try_args(&["--simulate", "--ring"]).unwrap();
        assert_eq!(
            flagged.segment,
            Some(Segment::Simulate {
                topology: None,
                ring: true
            })
        );
        let filed: Config = toml::from_str("[segment.simulate]\nring = true\n").unwrap();
        assert_eq!(filed.segment, flagged.segment);
        let plain: Config = toml::from_str("[segment.simulate]\n").unwrap();
        assert_eq!(
            plain.segment,
            Some(Segment::Simulate {
                topology: None,
                ring: false
            })
        );
        let refused = try_args(&["--iface", "eth0", "--ring"]).unwrap_err();
        assert!(refused.contains("needs --simulate"), "{refused}");
    }
}
