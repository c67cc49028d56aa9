//! What a command prints: a JSON value for `--json`, and its human form (text, or raw bytes
//! for file transfers so that `> file` gets the exact bytes).

use std::io::Write;

use serde_json::Value;

use crate::failure::Failure;

/// The human form of a result.
pub enum Human {
    /// Lines of text (nothing printed when empty).
    Text(String),
    /// Bytes written to standard output as they are.
    Bytes(Vec<u8>),
    /// Everything was printed as it came (a stream), in the form asked for: nothing is left
    /// to print in either form.
    Printed,
}

/// What a command prints.
pub struct Out {
    /// The `--json` form.
    pub json: Value,
    /// The default form.
    pub human: Human,
}

/// A result with a text form.
pub fn out(json: Value, human: impl Into<String>) -> Out {
    Out {
        json,
        human: Human::Text(human.into()),
    }
}

/// The result of a command that printed as it went (`--watch`).
pub fn printed() -> Out {
    Out {
        json: Value::Null,
        human: Human::Printed,
    }
}

/// A result whose default form is raw bytes.
pub fn bytes(json: Value, data: Vec<u8>) -> Out {
    Out {
        json,
        human: Human::Bytes(data),
    }
}

impl Out {
    /// Prints the JSON or the human form to standard output.
    pub fn print(self, json: bool) -> Result<(), Failure> {
        let mut stdout = std::io::stdout().lock();
        let written = if matches!(self.human, Human::Printed) {
            Ok(())
        } else if json {
            writeln!(stdout, "{}", self.json)
        } else {
            match self.human {
                Human::Text(text) if text.is_empty() => Ok(()),
                Human::Text(text) => writeln!(stdout, "{text}"),
                Human::Bytes(data) => stdout.write_all(&data),
                Human::Printed => Ok(()),
            }
        };
        written
            .and_then(|()| stdout.flush())
            .map_err(|err| Failure::other(format!("standard output: {err}")))
    }
}
