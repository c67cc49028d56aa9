//! `ecat foe_read` and `ecat foe_write` with IgH's arguments: `foe_read NAME [-o FILE]`
//! (raw bytes to standard output without `-o`), `foe_write FILE [-o NAME]` (the name on the
//! slave defaults to the file's own name). Both show a progress bar of the bytes streamed.

use std::path::PathBuf;

use proto::v1 as pb;
use serde_json::json;
use tokio_stream::StreamExt;

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, bytes, out};
use crate::parse::failed;
use crate::progress::bar;
use crate::select::Selection;
use crate::session::Session;

/// The size of one streamed write chunk.
const CHUNK: usize = 64 << 10;

/// `ecat foe_read`.
#[derive(Debug, clap::Args)]
pub struct FoeRead {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// File name on the slave.
    pub name: String,
    /// Where to write it (raw bytes to standard output when absent).
    #[arg(short = 'o', long = "output-file")]
    pub output: Option<PathBuf>,
    /// Password.
    #[arg(long, default_value = "0")]
    pub password: u32,
}

/// `ecat foe_write`.
#[derive(Debug, clap::Args)]
pub struct FoeWrite {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// The local file.
    pub file: PathBuf,
    /// File name on the slave (default: the local file's name).
    #[arg(short = 'o', long = "output-file")]
    pub name: Option<String>,
    /// Password.
    #[arg(long, default_value = "0")]
    pub password: u32,
}

impl Run for FoeRead {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "foe_read").await?;
        let mut stream = session
            .clients()
            .await?
            .foe
            .read(pb::FoeReadRequest {
                slave,
                name: self.name.clone(),
                password: self.password,
            })
            .await
            .map_err(failed)?
            .into_inner();
        let progress = bar(None, &self.name);
        let mut data = Vec::new();
        while let Some(chunk) = stream.message().await.map_err(failed)? {
            progress.inc(chunk.data.len() as u64);
            data.extend_from_slice(&chunk.data);
        }
        progress.finish_and_clear();
        match self.output {
            Some(path) => {
                std::fs::write(&path, &data)
                    .map_err(|e| Failure::other(format!("{}: {e}", path.display())))?;
                Ok(out(
                    json!({"bytes": data.len()}),
                    format!("{} bytes", data.len()),
                ))
            }
            None => Ok(bytes(json!({"data": hex::encode(&data)}), data)),
        }
    }
}

impl Run for FoeWrite {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "foe_write").await?;
        let file = &self.file;
        let data =
            std::fs::read(file).map_err(|e| Failure::other(format!("{}: {e}", file.display())))?;
        let name = match self.name {
            Some(name) => name,
            None => file
                .file_name()
                .map(|n| n.to_string_lossy().into_owned())
                .ok_or_else(|| format!("{}: no file name; give -o NAME", file.display()))?,
        };
        let progress = bar(Some(data.len() as u64), &name);
        let mut chunks: Vec<pb::FoeWriteChunk> = data
            .chunks(CHUNK)
            .map(|piece| pb::FoeWriteChunk {
                slave: slave.clone(),
                name: name.clone(),
                password: self.password,
                data: piece.to_vec(),
            })
            .collect();
        if chunks.is_empty() {
            chunks.push(pb::FoeWriteChunk {
                slave,
                name,
                password: self.password,
                data: Vec::new(),
            });
        }
        // Counted as tonic takes each chunk to send it.
        let counter = progress.clone();
        let stream = tokio_stream::iter(chunks).map(move |chunk| {
            counter.inc(chunk.data.len() as u64);
            chunk
        });
        let r = session
            .clients()
            .await?
            .foe
            .write(stream)
            .await
            .map_err(failed)?
            .into_inner();
        progress.finish_and_clear();
        Ok(out(
            json!({"written": r.written}),
            format!("{} bytes written", r.written),
        ))
    }
}
