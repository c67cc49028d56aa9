//! `ecat pcap -c N [-t SECONDS] -w FILE`: the live bus as a pcapng file for Wireshark
//! (standard output without `-w`), with a progress bar of the bytes received;
//! `ecat pcap --rolling -w FILE`: the rolling capture's window instead (its ring of files,
//! oldest first, as one pcapng file of several sections).

use std::path::PathBuf;

use proto::v1 as pb;
use serde_json::json;

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, bytes, out};
use crate::parse::{failed, num};
use crate::progress::bar;
use crate::session::Session;

/// `ecat pcap`.
#[derive(Debug, clap::Args)]
pub struct Pcap {
    /// Stop after this many frames.
    #[arg(short = 'c', long = "count")]
    pub count: Option<String>,
    /// Stop after this many seconds.
    #[arg(short = 't', long = "seconds")]
    pub seconds: Option<f64>,
    /// The pcapng file (standard output when absent).
    #[arg(short = 'w', long = "write")]
    pub file: Option<PathBuf>,
    /// Fetch the rolling capture's window (`[capture]` in ecatd's configuration) instead of
    /// capturing now.
    #[arg(long, conflicts_with_all = ["count", "seconds"])]
    pub rolling: bool,
}

impl Run for Pcap {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let frames = match &self.count {
            Some(text) => num(text, "count")?,
            None => 0,
        };
        let seconds = self.seconds.unwrap_or(0.0);
        if frames == 0 && seconds <= 0.0 && !self.rolling {
            return Err("pcap: give -c FRAMES, -t SECONDS or both".into());
        }
        if !(0.0..=600.0).contains(&seconds) {
            return Err("pcap: -t takes 0 to 600 seconds".into());
        }
        let mut stream = session
            .clients()
            .await?
            .bus
            .capture(pb::CaptureRequest {
                frames,
                duration_ms: (seconds * 1000.0) as u32,
                rolling: self.rolling,
            })
            .await
            .map_err(failed)?
            .into_inner();
        let progress = bar(None, "capture");
        let mut data = Vec::new();
        let (mut count, mut dropped) = (0, 0);
        while let Some(chunk) = stream.message().await.map_err(failed)? {
            progress.inc(chunk.data.len() as u64);
            data.extend_from_slice(&chunk.data);
            count = count.max(chunk.frames);
            dropped = dropped.max(chunk.dropped);
        }
        progress.finish_and_clear();
        if dropped > 0 {
            eprintln!("ecat: pcap: {dropped} frames dropped (the capture fell behind the bus)");
        }
        let json = json!({"frames": count, "dropped": dropped, "bytes": data.len()});
        match self.file {
            Some(path) => {
                std::fs::write(&path, &data)
                    .map_err(|e| Failure::other(format!("{}: {e}", path.display())))?;
                Ok(out(json, format!("{count} frames, {dropped} dropped")))
            }
            None => Ok(bytes(json, data)),
        }
    }
}
