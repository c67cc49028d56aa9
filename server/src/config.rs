//! ecatd's configuration: a TOML file, then `ECATD_*` environment variables, then flags
//! (flags win). `--print-config` shows the result.

use std::net::SocketAddr;
use std::path::PathBuf;

use clap::Parser;
use serde::{Deserialize, Serialize};

use crate::security::Token;

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
    /// gRPC listen address.
    #[arg(long, env = "ECATD_GRPC_LISTEN", value_name = "ADDR")]
    pub grpc_listen: Option<SocketAddr>,
    /// HTTP listen address (REST, metrics, health).
    #[arg(long, env = "ECATD_HTTP_LISTEN", value_name = "ADDR")]
    pub http_listen: Option<SocketAddr>,
    /// ETG.8200 mailbox gateway listen address (UDP).
    #[arg(long, env = "ECATD_GATEWAY_LISTEN", value_name = "ADDR")]
    pub gateway_listen: Option<SocketAddr>,
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
    /// Print the effective configuration as TOML and exit.
    #[arg(long)]
    pub print_config: bool,
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
    },
    /// A network interface.
    Iface {
        /// Interface name.
        name: String,
    },
}

/// The mailbox gateway's settings (`[gateway]`).
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GatewaySettings {
    /// UDP listen address; default 127.0.0.1:34980 (ETG.8200's port). Port 0: any free port.
    /// A taken port falls back to a free one, which the log and the metrics report.
    pub listen: SocketAddr,
    /// Client networks allowed to send requests (CIDR, e.g. `10.0.0.0/8`); empty: loopback
    /// only.
    pub allow: Vec<String>,
    /// Strict mode: no error replies from the gateway itself (ETG.8200 permits silence).
    pub strict: bool,
}

impl Default for GatewaySettings {
    fn default() -> GatewaySettings {
        GatewaySettings {
            listen: SocketAddr::from(([127, 0, 0, 1], master_core::gateway::DEFAULT_PORT)),
            allow: Vec::new(),
            strict: false,
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
    pub watch: Vec<crate::watch::WatchSpec>,
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
        if let Some(topology) = &args.simulate {
            config.segment = Some(Segment::Simulate {
                topology: (!topology.is_empty()).then(|| PathBuf::from(topology)),
            });
        }
        if let Some(name) = &args.iface {
            config.segment = Some(Segment::Iface { name: name.clone() });
        }
        if let Some(addr) = args.grpc_listen {
            config.grpc_listen = addr;
        }
        if let Some(addr) = args.http_listen {
            config.http_listen = addr;
        }
        if args.no_gateway {
            config.gateway = None;
        } else if let Some(addr) = args.gateway_listen {
            config
                .gateway
                .get_or_insert_with(GatewaySettings::default)
                .listen = addr;
        }
        if let Some(format) = args.log_format {
            config.log_format = format;
        }
        if let Some(log) = &args.log {
            config.log = log.clone();
        }
        config.insecure |= args.insecure;
        if let (Some(cert), Some(key)) = (&args.tls_cert, &args.tls_key) {
            config.tls = Some(TlsSettings {
                cert: cert.clone(),
                key: key.clone(),
            });
        }
        Ok(config)
    }

    /// Refuses a non-loopback listen address without tokens, unless `insecure`.
    pub fn check(&self) -> Result<(), String> {
        crate::watch::spec::check_all(&self.watch)?;
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
            token.token = "***".into();
        }
        toml::to_string(&shown).unwrap_or_else(|err| format!("# cannot show: {err}\n"))
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
        assert_eq!(flagged.segment, Some(Segment::Simulate { topology: None }));
        let round = toml::from_str::<Config>(&flagged.to_toml()).unwrap();
        assert_eq!(round, flagged);
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
            token: "s".into(),
            role: crate::security::Role::Read,
        });
        assert!(tokened.check().is_ok());
        assert!(!tokened.to_toml().contains("\"s\""));
    }

    #[test]
    fn unknown_keys_are_refused() {
        assert!(toml::from_str::<Config>("grpc_lisen = \"127.0.0.1:1\"").is_err());
    }
}
