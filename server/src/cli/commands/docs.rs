//! `ecat completions SHELL` and `ecat man [COMMAND] [--out DIR]`: generated from the clap
//! definitions, so they cannot drift from the commands. `man --out DIR` writes every page:
//! `ecat.1`, `ecat-COMMAND.1` for each command, and `ecatd.8` for the daemon.

use std::path::PathBuf;

use clap::CommandFactory;
use serde_json::json;

use crate::failure::Failure;
use crate::out::{Out, bytes, out};
use crate::session::Session;
use crate::{Cli, Run};

/// `ecat completions`.
#[derive(Debug, clap::Args)]
pub struct Completion {
    /// The shell.
    pub shell: clap_complete::Shell,
}

/// `ecat man`.
#[derive(Debug, clap::Args)]
pub struct Man {
    /// The command whose page to print (`slaves`, `upload`, ...; `ecatd` for the daemon);
    /// ecat's own page without one.
    #[arg(value_name = "COMMAND", conflicts_with = "out")]
    pub command: Option<String>,
    /// Write every page into DIR (`ecat.1`, `ecat-COMMAND.1`, `ecatd.8`) instead.
    #[arg(long, value_name = "DIR")]
    pub out: Option<PathBuf>,
}

impl Run for Completion {
    async fn run(self, _: &mut Session) -> Result<Out, Failure> {
        let mut script = Vec::new();
        clap_complete::generate(self.shell, &mut Cli::command(), "ecat", &mut script);
        Ok(bytes(
            json!({"shell": self.shell.to_string(), "script": String::from_utf8_lossy(&script)}),
            script,
        ))
    }
}

/// One man page: its file name and the command it describes.
struct Page {
    file: String,
    command: clap::Command,
}

/// Every page: ecat's, one per command (named `ecat-COMMAND`, its usage `ecat COMMAND`), and
/// ecatd's (section 8, a daemon).
fn pages() -> Vec<Page> {
    let mut ecat = Cli::command();
    ecat.build();
    let mut pages = vec![Page {
        file: "ecat.1".into(),
        command: ecat.clone(),
    }];
    // Built, each command has the display name `ecat-COMMAND` and the usage `ecat COMMAND`.
    // clap's own `help` command has no page: `ecat help X` is `ecat X --help`.
    for command in ecat.get_subcommands().filter(|c| c.get_name() != "help") {
        pages.push(Page {
            file: format!("ecat-{}.1", command.get_name()),
            command: command.clone().version(env!("CARGO_PKG_VERSION")),
        });
    }
    pages.push(Page {
        file: "ecatd.8".into(),
        command: server::config::Args::command(),
    });
    pages
}

/// A page as roff.
fn render(page: &Page) -> Result<Vec<u8>, Failure> {
    let section = page.file.rsplit('.').next().unwrap_or("1").to_owned();
    let mut roff = Vec::new();
    clap_mangen::Man::new(page.command.clone())
        .section(section)
        .render(&mut roff)
        .map_err(|err| Failure::other(format!("man page {}: {err}", page.file)))?;
    Ok(roff)
}

impl Run for Man {
    async fn run(self, _: &mut Session) -> Result<Out, Failure> {
        let pages = pages();
        if let Some(dir) = self.out {
            std::fs::create_dir_all(&dir)
                .map_err(|err| Failure::other(format!("{}: {err}", dir.display())))?;
            let mut written = Vec::new();
            for page in &pages {
                let path = dir.join(&page.file);
                std::fs::write(&path, render(page)?)
                    .map_err(|err| Failure::other(format!("{}: {err}", path.display())))?;
                written.push(path.display().to_string());
            }
            return Ok(out(json!({"written": written}), written.join("\n")));
        }
        let file = match self.command.as_deref() {
            None => "ecat.1".to_owned(),
            Some("ecatd") => "ecatd.8".to_owned(),
            Some(name) => {
                // A command as it is typed: its name, an alias or an abbreviation.
                let candidates = crate::abbrev::candidates(name);
                let exact = Cli::command()
                    .find_subcommand(name)
                    .map(|c| c.get_name().to_owned());
                match (exact, candidates.as_slice()) {
                    (Some(command), _) => format!("ecat-{command}.1"),
                    (None, [command]) => format!("ecat-{command}.1"),
                    (None, []) => return Err(format!("man: no command {name:?}").into()),
                    (None, many) => {
                        return Err(format!(
                            "man: {name:?} is ambiguous: it begins {}",
                            many.join(", ")
                        )
                        .into());
                    }
                }
            }
        };
        let page = pages
            .iter()
            .find(|page| page.file == file)
            .ok_or_else(|| Failure::other(format!("man: no page {file}")))?;
        let roff = render(page)?;
        Ok(bytes(json!({"roff": String::from_utf8_lossy(&roff)}), roff))
    }
}
