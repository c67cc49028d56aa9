//! `ecat sii_read` (the image as raw bytes, to standard output or `-o FILE`) and
//! `ecat sii_write FILE` (a whole image; its checksum, the CRC-8 of words 0-6 in the low
//! byte of word 7, is checked first: ETG.2010, spec-notes §sii.fixed).

use std::path::PathBuf;

use master_core::wire::sii::checksum::{CHECKSUM_OFFSET, CHECKSUM_SPAN, crc8};
use proto::v1 as pb;
use serde_json::json;

use crate::Run;
use crate::failure::Failure;
use crate::out::{Out, bytes, out};
use crate::parse::failed;
use crate::select::Selection;
use crate::session::Session;

/// `ecat sii_read`.
#[derive(Debug, clap::Args)]
pub struct SiiRead {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// Where to write it (raw bytes to standard output when absent).
    #[arg(short = 'o', long = "output-file")]
    pub output: Option<PathBuf>,
}

/// `ecat sii_write`.
#[derive(Debug, clap::Args)]
pub struct SiiWrite {
    /// The slave.
    #[command(flatten)]
    pub select: Selection,
    /// The image file (`-` for standard input).
    pub file: PathBuf,
    /// Recompute the checksum (word 7) instead of refusing an image whose checksum is
    /// wrong.
    #[arg(long, conflicts_with = "force")]
    pub fix: bool,
    /// Write the image as it is, checksum or not.
    #[arg(long)]
    pub force: bool,
}

impl Run for SiiRead {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let slave = self.select.one(session, "sii_read").await?;
        let r = session
            .clients()
            .await?
            .bus
            .read_sii(pb::ReadSiiRequest { slave })
            .await
            .map_err(failed)?
            .into_inner();
        match self.output {
            Some(path) => {
                std::fs::write(&path, &r.data)
                    .map_err(|e| Failure::other(format!("{}: {e}", path.display())))?;
                Ok(out(
                    json!({"bytes": r.data.len()}),
                    format!("{} bytes", r.data.len()),
                ))
            }
            None => Ok(bytes(json!({"data": hex::encode(&r.data)}), r.data)),
        }
    }
}

/// Reads the image and checks it: an even size of at least the configuration area, and
/// the checksum right (or fixed with `fix`, or not checked with `force`).
fn image(file: &std::path::Path, fix: bool, force: bool) -> Result<Vec<u8>, Failure> {
    let mut data = if file.as_os_str() == "-" {
        let mut data = Vec::new();
        std::io::Read::read_to_end(&mut std::io::stdin(), &mut data)
            .map_err(|e| Failure::other(format!("standard input: {e}")))?;
        data
    } else {
        std::fs::read(file).map_err(|e| Failure::other(format!("{}: {e}", file.display())))?
    };
    if data.len() < CHECKSUM_OFFSET + 2 || !data.len().is_multiple_of(2) {
        return Err(format!(
            "{}: {} bytes is no SII image (an even number, at least 16)",
            file.display(),
            data.len()
        )
        .into());
    }
    let want = crc8(&data[..CHECKSUM_SPAN]);
    let have = data[CHECKSUM_OFFSET];
    if have != want && !force {
        if fix {
            data[CHECKSUM_OFFSET] = want;
        } else {
            return Err(format!(
                "{}: SII checksum 0x{have:02x} is wrong (words 0-6 give 0x{want:02x}); \
                 --fix to correct it, --force to write it as it is",
                file.display()
            )
            .into());
        }
    }
    Ok(data)
}

impl Run for SiiWrite {
    async fn run(self, session: &mut Session) -> Result<Out, Failure> {
        let data = image(&self.file, self.fix, self.force)?;
        let slave = self.select.one(session, "sii_write").await?;
        session
            .clients()
            .await?
            .bus
            .write_sii(pb::WriteSiiRequest {
                slave,
                word: 0,
                data: data.clone(),
                force: self.force,
            })
            .await
            .map_err(failed)?;
        Ok(out(
            json!({"written": data.len()}),
            format!("{} bytes written", data.len()),
        ))
    }
}
