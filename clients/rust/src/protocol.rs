//! The lines of the attach socket (docs/application.md, "The protocol"): ASCII, one per
//! request, answer or event, ended by `\n`, at most [`MAX_LINE`] bytes.

use std::fmt;

/// The protocol version this library speaks.
pub const VERSION: u32 = 1;
/// The longest line either side sends or accepts, newline included.
pub const MAX_LINE: usize = 256;

/// What a program asks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Request {
    /// Attach: the protocol version, and whether the program may claim later (`rw`).
    Hello {
        /// Protocol version.
        version: u32,
        /// `rw` rather than `ro`.
        writable: bool,
    },
    /// Take the outputs.
    Claim,
    /// Give the outputs back.
    Release,
    /// Is ecatd there?
    Ping,
}

impl Request {
    /// Parses one line (without its newline).
    pub fn parse(line: &str) -> Result<Request, String> {
        let mut words = line.split(' ');
        let request = match (words.next(), words.next(), words.next()) {
            (Some("HELLO"), Some(version), Some(mode)) => {
                let version = version
                    .parse()
                    .map_err(|_| format!("HELLO: version {version:?} is not a number"))?;
                let writable = match mode {
                    "rw" => true,
                    "ro" => false,
                    other => return Err(format!("HELLO: mode {other:?} is not ro or rw")),
                };
                Request::Hello { version, writable }
            }
            (Some("CLAIM"), None, None) => Request::Claim,
            (Some("RELEASE"), None, None) => Request::Release,
            (Some("PING"), None, None) => Request::Ping,
            _ => return Err(format!("unknown request {:?}", truncate(line))),
        };
        if words.next().is_some() {
            return Err(format!("unknown request {:?}", truncate(line)));
        }
        Ok(request)
    }
}

impl fmt::Display for Request {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Request::Hello { version, writable } => {
                write!(f, "HELLO {version} {}", if *writable { "rw" } else { "ro" })
            }
            Request::Claim => f.write_str("CLAIM"),
            Request::Release => f.write_str("RELEASE"),
            Request::Ping => f.write_str("PING"),
        }
    }
}

/// What ecatd sends: an answer to the last request, or an event.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Line {
    /// Attached: the layout generation and the image region's bytes (an image region and
    /// an eventfd come with it).
    Hello {
        /// Layout generation.
        generation: u32,
        /// Bytes to map.
        region_len: usize,
    },
    /// The outputs are the program's: the commit region's bytes (the region comes with it).
    Claimed {
        /// Bytes to map.
        region_len: usize,
    },
    /// The outputs were given back.
    Released,
    /// ecatd is there.
    Pong,
    /// The request was refused, with the reason.
    Refused(String),
    /// A new layout generation replaced the program's region.
    LayoutChanged(u32),
    /// The program lost the outputs to the watchdog.
    Watchdog,
    /// ecatd is stopping.
    Shutdown,
}

impl Line {
    /// Parses one line from ecatd (without its newline).
    pub fn parse(line: &str) -> Result<Line, String> {
        let words: Vec<&str> = line.splitn(3, ' ').collect();
        let number = |word: &str| -> Result<usize, String> {
            word.parse()
                .map_err(|_| format!("{:?}: {word:?} is not a number", truncate(line)))
        };
        Ok(match words.as_slice() {
            ["OK", "HELLO", rest] => {
                let (generation, region) = rest
                    .split_once(' ')
                    .ok_or_else(|| format!("{:?}: two numbers expected", truncate(line)))?;
                Line::Hello {
                    generation: u32::try_from(number(generation)?)
                        .map_err(|_| format!("{generation}: generation too large"))?,
                    region_len: number(region)?,
                }
            }
            ["OK", "CLAIM", region] => Line::Claimed {
                region_len: number(region)?,
            },
            ["OK", "RELEASE"] => Line::Released,
            ["OK", "PING"] => Line::Pong,
            ["ERR", reason @ ..] => Line::Refused(one_line(&reason.join(" ")).into_owned()),
            ["EVENT", "layout_changed", generation] => Line::LayoutChanged(
                u32::try_from(number(generation)?)
                    .map_err(|_| format!("{generation}: generation too large"))?,
            ),
            ["EVENT", "watchdog"] => Line::Watchdog,
            ["EVENT", "shutdown"] => Line::Shutdown,
            _ => return Err(format!("unknown line {:?}", truncate(line))),
        })
    }

    /// Whether this line is an event rather than the answer to a request.
    pub fn is_event(&self) -> bool {
        matches!(
            self,
            Line::LayoutChanged(_) | Line::Watchdog | Line::Shutdown
        )
    }
}

impl fmt::Display for Line {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Line::Hello {
                generation,
                region_len,
            } => write!(f, "OK HELLO {generation} {region_len}"),
            Line::Claimed { region_len } => write!(f, "OK CLAIM {region_len}"),
            Line::Released => f.write_str("OK RELEASE"),
            Line::Pong => f.write_str("OK PING"),
            Line::Refused(reason) => write!(f, "ERR {}", one_line(reason)),
            Line::LayoutChanged(generation) => write!(f, "EVENT layout_changed {generation}"),
            Line::Watchdog => f.write_str("EVENT watchdog"),
            Line::Shutdown => f.write_str("EVENT shutdown"),
        }
    }
}

/// A refusal's reason as it goes on the wire: line breaks become spaces (a reason is never
/// two lines) and it is cut so that `ERR <reason>\n` stays within [`MAX_LINE`]. Parsing
/// applies the same, so a parsed reason prints back to the same line.
fn one_line(reason: &str) -> std::borrow::Cow<'_, str> {
    let mut end = reason.len().min(MAX_LINE - "ERR \n".len());
    while !reason.is_char_boundary(end) {
        end -= 1;
    }
    let cut = &reason[..end];
    if cut.contains(['\n', '\r']) {
        cut.replace(['\n', '\r'], " ").into()
    } else {
        cut.into()
    }
}

/// `text` cut so that a line quoting it stays within [`MAX_LINE`].
fn truncate(text: &str) -> &str {
    let mut end = text.len().min(MAX_LINE / 2);
    while !text.is_char_boundary(end) {
        end -= 1;
    }
    &text[..end]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn requests_and_lines_round_trip() {
        for r in [
            Request::Hello {
                version: 1,
                writable: true,
            },
            Request::Hello {
                version: 1,
                writable: false,
            },
            Request::Claim,
            Request::Release,
            Request::Ping,
        ] {
            assert_eq!(Request::parse(&r.to_string()), Ok(r));
        }
        for l in [
            Line::Hello {
                generation: 3,
                region_len: 8192,
            },
            Line::Claimed { region_len: 4096 },
            Line::Released,
            Line::Pong,
            Line::Refused("owned pid=12 uid=0".into()),
            Line::LayoutChanged(4),
            Line::Watchdog,
            Line::Shutdown,
        ] {
            assert_eq!(Line::parse(&l.to_string()), Ok(l));
        }
    }

    #[test]
    fn malformed_requests_are_refused_with_a_reason() {
        assert!(
            Request::parse("HELLO x rw")
                .unwrap_err()
                .contains("version")
        );
        assert!(Request::parse("HELLO 1 wr").unwrap_err().contains("mode"));
        assert!(Request::parse("CLAIM now").is_err());
        assert!(Request::parse("").is_err());
        assert!(Request::parse(&"A".repeat(1000)).unwrap_err().len() < MAX_LINE);
        assert!(Line::parse("OK HELLO 1").is_err());
        assert!(Line::parse("OK CLAIM -1").is_err());
    }

    #[test]
    fn a_refusal_is_one_line_within_the_limit_and_prints_back_as_parsed() {
        let long = Line::Refused(format!("first\nsecond {}", "é".repeat(300)));
        let text = long.to_string();
        assert!(!text.contains('\n'), "{text:?}");
        assert!(text.len() < MAX_LINE, "{} bytes", text.len());
        let parsed = Line::parse(&text).unwrap();
        assert_eq!(parsed.to_string(), text);
        assert_eq!(Line::parse(&parsed.to_string()), Ok(parsed));
    }
}
