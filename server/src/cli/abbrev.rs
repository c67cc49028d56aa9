//! Abbreviated commands, as IgH's `ethercat` takes them: clap's `infer_subcommands` runs
//! the one command a prefix names (`ecat sl` is `slaves`; a command's full name wins over
//! the longer commands it begins, `pd` over `pdos`). A prefix of several commands gets a
//! usage error naming them, where clap alone would only call it unrecognised.

use clap::CommandFactory;
use clap::error::{ContextKind, ContextValue, ErrorKind};

use crate::Cli;

/// `err` as is, or for a prefix of several commands the usage error that lists them.
pub fn ambiguity(err: clap::Error) -> clap::Error {
    if err.kind() != ErrorKind::InvalidSubcommand {
        return err;
    }
    let Some(ContextValue::String(word)) = err.get(ContextKind::InvalidSubcommand) else {
        return err;
    };
    let candidates = candidates(word);
    if candidates.len() < 2 {
        return err;
    }
    Cli::command().error(
        ErrorKind::InvalidSubcommand,
        format!(
            "the command '{word}' is ambiguous: it begins {}; type more of it",
            candidates.join(", ")
        ),
    )
}

/// The commands whose name or alias begins with `prefix`, each once.
pub fn candidates(prefix: &str) -> Vec<String> {
    Cli::command()
        .get_subcommands()
        .filter(|command| {
            command.get_name().starts_with(prefix)
                || command.get_all_aliases().any(|a| a.starts_with(prefix))
        })
        .map(|command| command.get_name().to_owned())
        .collect()
}

#[cfg(test)]
mod tests {
    use clap::Parser;

    use crate::{Cli, Command};

    #[test]
    fn a_unique_prefix_runs_its_command_and_a_full_name_wins() {
        let cli = Cli::try_parse_from(["ecat", "sl"]).expect("sl is slaves");
        assert!(matches!(cli.command, Command::Slaves(_)));
        let cli = Cli::try_parse_from(["ecat", "pd"]).expect("pd is a command");
        assert!(matches!(cli.command, Command::Pd(_)));
        let cli = Cli::try_parse_from(["ecat", "comp", "bash"]).expect("one command");
        assert!(matches!(cli.command, Command::Completions(_)));
    }

    #[test]
    fn an_ambiguous_prefix_names_its_candidates() {
        let err = Cli::try_parse_from(["ecat", "s"]).expect_err("s is ambiguous");
        let text = super::ambiguity(err).to_string();
        for name in ["slaves", "sdos", "states", "soe_read", "sii_write"] {
            assert!(text.contains(name), "{name} missing: {text}");
        }
    }
}
