//! Events: `GET /api/v1/events` answers the kept history as JSON, filtered by time, kind and
//! slave; the same path asked with `Accept: text/event-stream` is the live stream, which a
//! client resumes with `Last-Event-ID` (the kept events after that number come first).

use std::time::SystemTime;

use axum::extract::State;
use axum::http::HeaderMap;
use axum::http::header::ACCEPT;
use axum::response::sse::{Event, KeepAlive, Sse};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use tokio_stream::StreamExt;
use tokio_stream::wrappers::BroadcastStream;
use tokio_stream::wrappers::errors::BroadcastStreamRecvError;
use utoipa::IntoParams;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::Result;
use crate::http::extract::{Json, Query};
use crate::input::since::parse_since;
use crate::service::history::{DEFAULT_LIMIT, EventQuery};
use crate::service::{ApiError, Core, EventView, parse_name};

/// The routes, each declared once (method and path come from the handler's annotation).
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new().routes(routes!(events))
}

/// Which kept events to answer (the history; the live stream takes none of these).
#[derive(Debug, Default, Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct EventsQuery {
    /// Only events published since: a time (RFC 3339, `2026-11-29T07:00:00Z`) or a span
    /// back from now (`10m`, `2h`).
    pub since: Option<String>,
    /// Only events of this kind (`state_changed`, `slave_lost`, `al_error`, ...).
    pub kind: Option<String>,
    /// Only events of this slave (any slave name; a position names a slave gone since).
    pub slave: Option<String>,
    /// At most this many, the newest (default 1000; with the stream, of the kept events it
    /// sends first).
    pub limit: Option<usize>,
}

impl EventsQuery {
    fn typed(&self) -> Result<EventQuery> {
        let now = SystemTime::now();
        Ok(EventQuery {
            since: self
                .since
                .as_deref()
                .map(|text| parse_since(text, now))
                .transpose()?,
            kind: self.kind.clone(),
            slave: self.slave.as_deref().map(parse_name).transpose()?,
            limit: Some(self.limit.unwrap_or(DEFAULT_LIMIT)),
        })
    }
}

#[utoipa::path(get, path = "/events", tag = "bus", params(EventsQuery,
        ("Last-Event-ID" = Option<u64>, Header, description = "With the stream: the last event number the client saw; the kept events after it come first")),
    responses((status = 200, description = "The kept events, oldest first; with `Accept: text/event-stream`, server-sent events (`id`: the event's number, `event`: its kind, data: one EventView)", body = [EventView]),
              (status = 400, body = crate::http::error::ErrorBody)))]
/// The event history, or with `Accept: text/event-stream` the live event stream.
pub async fn events(
    State(core): State<Core>,
    headers: HeaderMap,
    Query(query): Query<EventsQuery>,
) -> Result<Response> {
    let stream = headers
        .get(ACCEPT)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|accept| accept.contains("text/event-stream"));
    if !stream {
        return Ok(Json(core.event_history(query.typed()?)?).into_response());
    }
    let after = headers
        .get("last-event-id")
        .map(|v| {
            v.to_str()
                .ok()
                .and_then(|text| text.trim().parse::<u64>().ok())
                .ok_or_else(|| {
                    ApiError::invalid_field("last_event_id", "Last-Event-ID must be a number")
                })
        })
        .transpose()?;
    Ok(live(core, after, query.limit).into_response())
}

/// The live stream, after the kept events numbered above `after` when given (the newest
/// `limit` of them).
fn live(
    core: Core,
    after: Option<u64>,
    limit: Option<usize>,
) -> Sse<impl futures_util::Stream<Item = std::result::Result<Event, std::convert::Infallible>>> {
    let (past, live) = core.events_from(after, limit);
    let past = tokio_stream::iter(past.into_iter().map(Ok::<_, BroadcastStreamRecvError>));
    let stream = past.chain(BroadcastStream::new(live)).map(|item| {
        let view = match item {
            Ok(view) => view,
            Err(BroadcastStreamRecvError::Lagged(missed)) => EventView::lagged(missed),
        };
        let mut event = Event::default().event(view.kind.clone());
        // A `lagged` note has no number: the client's last one stays its resume point.
        if view.id != 0 {
            event = event.id(view.id.to_string());
        }
        Ok(event
            .json_data(&view)
            .unwrap_or_else(|_| Event::default().comment("unencodable")))
    });
    // Ends at shutdown, so that the server's graceful stop does not wait for it.
    let stream = futures_util::StreamExt::take_until(stream, core.stopped());
    Sse::new(stream).keep_alive(KeepAlive::default())
}
