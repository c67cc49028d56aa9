//! `GET /api/v1/capture?frames=N&seconds=S`: the live bus as a pcapng file;
//! `?rolling=true`: the rolling capture's window instead.

use axum::extract::State;
use axum::http::header::{CONTENT_TYPE, HeaderName};
use axum::response::IntoResponse;
use serde::Deserialize;
use utoipa::IntoParams;
use utoipa_axum::router::OpenApiRouter;
use utoipa_axum::routes;

use super::{Result, num};
use crate::http::extract::Admit;
use crate::http::extract::Query;
use crate::service::Core;
use crate::service::op;

/// The routes.
pub(super) fn routes() -> OpenApiRouter<Core> {
    OpenApiRouter::new().routes(routes!(capture))
}

/// How long to capture.
#[derive(Debug, Deserialize, IntoParams)]
pub struct CaptureQuery {
    /// Stop after this many frames (decimal or 0x hex).
    pub frames: Option<String>,
    /// Stop after this many seconds (decimal).
    pub seconds: Option<f64>,
    /// The rolling capture's window (its files, oldest first, as one pcapng file of
    /// several sections) instead of a live capture; `frames` and `seconds` are ignored.
    pub rolling: Option<bool>,
}

#[utoipa::path(get, path = "/capture", tag = "bus", params(CaptureQuery),
    responses((status = 200, description = "pcapng file", content_type = "application/x-pcapng")))]
/// Captures the live bus for a number of frames or seconds; the `x-ecat-dropped` header
/// counts the frames the capture could not keep up with.
pub async fn capture(
    Admit(ticket, _): Admit<op::Capture>,
    State(core): State<Core>,
    Query(q): Query<CaptureQuery>,
) -> Result<impl IntoResponse> {
    if q.rolling == Some(true) {
        let done = core.rolling_window(ticket).await?;
        return Ok(pcapng_response(done));
    }
    let frames = match &q.frames {
        Some(text) => num(text, "frames")?,
        None => 0,
    };
    let seconds = q.seconds.unwrap_or(0.0);
    if !(0.0..=600.0).contains(&seconds) {
        return Err(crate::service::ApiError::invalid_field(
            "seconds",
            "seconds must be 0..=600",
        ));
    }
    let done = core
        .capture(ticket, frames, std::time::Duration::from_secs_f64(seconds))
        .await?;
    Ok(pcapng_response(done))
}

fn pcapng_response(done: crate::service::capture::CaptureResult) -> impl IntoResponse {
    (
        [
            (CONTENT_TYPE, "application/x-pcapng".to_owned()),
            (
                HeaderName::from_static("x-ecat-frames"),
                done.frames.to_string(),
            ),
            (
                HeaderName::from_static("x-ecat-dropped"),
                done.dropped.to_string(),
            ),
        ],
        done.pcapng,
    )
}
