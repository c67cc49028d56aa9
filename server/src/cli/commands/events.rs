//! `ecat events`: the events ecatd kept (`--since 10m`, `--kind`, `-p`, `-n`), oldest first,
//! with the time ecatd published each; `-f` then follows the new ones as they come, from the
//! last one shown (nothing missed, nothing twice).

use std::io::Write;

use proto::v1 as pb;
use serde_json::{Value, json};

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, out, printed};
use crate::parse::failed;
use crate::select::Selection;
use crate::session::Session;

/// `ecat events`.
#[derive(Debug, clap::Args)]
pub struct Events {
    /// Only this slave's events.
    #[command(flatten)]
    pub select: Selection,
    /// Only events since a time (`2026-11-29T07:00:00Z`) or a span back (`10m`, `2h`).
    #[arg(long, value_name = "WHEN")]
    pub since: Option<String>,
    /// Only events of this kind (`state_changed`, `al_error`, `slave_lost`, ...).
    #[arg(long)]
    pub kind: Option<String>,
    /// At most this many, the newest.
    #[arg(short = 'n', long, default_value_t = 1000)]
    pub limit: u32,
    /// Then follow the new events until ecatd ends the stream or the command is stopped.
    #[arg(short = 'f', long)]
    pub follow: bool,
}

impl Run for Events {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.given()?.unwrap_or_default();
        let kind = self.kind.clone().unwrap_or_default();
        let kept = session
            .clients()
            .await?
            .bus
            .list_events(pb::ListEventsRequest {
                since: self.since.clone().unwrap_or_default(),
                kind: kind.clone(),
                slave: slave.clone(),
                limit: self.limit,
            })
            .await
            .map_err(failed)?
            .into_inner()
            .events;
        if !self.follow {
            let human = kept.iter().map(line).collect::<Vec<_>>().join("\n");
            return Ok(out(
                Value::Array(kept.iter().map(event_json).collect()),
                human,
            ));
        }
        let json = session.json();
        for event in &kept {
            print(event, json)?;
        }
        // From the last event the history had (or, with none, from the start of the history):
        // the stream sends what came since first.
        let after = kept.last().map_or(0, |e| e.id);
        let mut stream = session
            .clients()
            .await?
            .bus
            .watch_events(pb::WatchEventsRequest {
                after: Some(after),
                limit: 0,
            })
            .await
            .map_err(failed)?
            .into_inner();
        let position = match kept_position(&slave) {
            Some(position) => Some(position),
            None if slave.is_empty() => None,
            None => Some(
                session
                    .clients()
                    .await?
                    .bus
                    .get_slave(pb::GetSlaveRequest { slave })
                    .await
                    .map_err(failed)?
                    .into_inner()
                    .position,
            ),
        };
        while let Some(event) = stream.message().await.map_err(failed)? {
            let wanted = (kind.is_empty() || event.kind == kind)
                && position.is_none_or(|p| event.position == p)
                && event.kind != "foe_progress";
            if wanted {
                print(&event, json)?;
            }
        }
        Ok(printed())
    }
}

/// The position a plain slave name gives (`3`, `pos:3`), for filtering the followed events;
/// other names are asked of ecatd.
fn kept_position(slave: &str) -> Option<u32> {
    let slave = slave.trim();
    slave.strip_prefix("pos:").unwrap_or(slave).parse().ok()
}

fn print(event: &pb::Event, json: bool) -> Result<(), Failure> {
    let mut stdout = std::io::stdout().lock();
    let text = if json {
        event_json(event).to_string()
    } else {
        line(event)
    };
    writeln!(stdout, "{text}")
        .and_then(|()| stdout.flush())
        .map_err(|err| Failure::other(format!("standard output: {err}")))
}

/// One event as a line: time, kind, text.
fn line(event: &pb::Event) -> String {
    format!("{}  {:<16} {}", event.time, event.kind, event.text)
}

fn event_json(event: &pb::Event) -> Value {
    json!({
        "id": event.id,
        "time": event.time,
        "kind": event.kind,
        "position": event.position,
        "station": event.station,
        "name": event.name,
        "text": event.text,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_line_is_time_kind_and_words() {
        let event = pb::Event {
            id: 7,
            time: "2026-11-29T07:00:00.000Z".into(),
            kind: "slave_lost".into(),
            text: "slave 2 (EL2008) lost".into(),
            ..pb::Event::default()
        };
        assert_eq!(
            line(&event),
            "2026-11-29T07:00:00.000Z  slave_lost       slave 2 (EL2008) lost"
        );
        assert_eq!(event_json(&event)["id"], 7);
        assert_eq!(kept_position("pos:3"), Some(3));
        assert_eq!(kept_position("station:1004"), None);
    }
}
