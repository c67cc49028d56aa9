//! A link wrapper that records the bus in a pcap file, for Wireshark.
//!
//! Every frame sent and every frame received through the tap is appended, with the time it
//! passed, as an Ethernet packet. Wireshark's EtherCAT dissectors then show the whole
//! conversation between master and slaves.

use std::fs::File;
use std::io::{self, BufWriter, Write};
use std::path::Path;
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::time::{SystemTime, UNIX_EPOCH};

use pcap_file::pcap::{PcapHeader, PcapPacket, PcapWriter};
use pcap_file::{DataLink, Endianness, PcapError, TsResolution};

use super::{Link, Wait};

/// Wraps a link and appends every frame that passes, in both directions, to a pcap capture.
///
/// Frames are recorded after they passed: a sent frame once the inner link accepted it, a
/// received frame once it arrived. Capturing never disturbs the traffic: if writing the
/// capture fails (disk full, say) the tap stops capturing, keeps the first error, and
/// reports it from [`PcapTap::flush`] and [`PcapTap::capture_error`], while frames go on
/// flowing.
///
/// Writes go through a [`BufWriter`]; the capture is complete on disk after
/// [`PcapTap::flush`] or when the tap is dropped.
///
/// Where the tap sits decides what it sees: outside a [`FaultInjector`](super::FaultInjector)
/// it records what the master believes it sent and received, inside one it records what the
/// (faulty) wire carried.
#[derive(Debug)]
pub struct PcapTap<L: Link, W: Write + Send = File> {
    inner: L,
    writer: PcapWriter<SharedWriter<W>>,
    /// The same buffered writer the pcap writer uses. pcap-file 2's writer offers no way back
    /// to its writer short of consuming itself, so the tap keeps a second handle to flush.
    /// Only the tap uses either handle, always through `&mut self`, so the lock is never
    /// contended.
    buffer: Arc<Mutex<BufWriter<W>>>,
    /// The first capture error; once set, nothing more is written.
    error: Option<io::Error>,
}

impl<L: Link> PcapTap<L> {
    /// Wraps `inner` and records its traffic in a new file at `path` (replacing any file
    /// there).
    pub fn create(inner: L, path: impl AsRef<Path>) -> io::Result<PcapTap<L>> {
        let path = path.as_ref();
        let file = File::create(path).map_err(|err| {
            io::Error::new(
                err.kind(),
                format!("cannot create pcap file {}: {err}", path.display()),
            )
        })?;
        PcapTap::new(inner, file)
    }
}

impl<L: Link, W: Write + Send> PcapTap<L, W> {
    /// Wraps `inner` and records its traffic into `writer`, starting with the pcap file
    /// header (Ethernet link type, nanosecond timestamps).
    pub fn new(inner: L, writer: W) -> io::Result<PcapTap<L, W>> {
        let buffer = Arc::new(Mutex::new(BufWriter::new(writer)));
        let header = PcapHeader {
            datalink: DataLink::ETHERNET,
            ts_resolution: TsResolution::NanoSecond,
            endianness: Endianness::native(),
            ..PcapHeader::default()
        };
        let writer = PcapWriter::with_header(SharedWriter(Arc::clone(&buffer)), header)
            .map_err(into_io_error)?;
        Ok(PcapTap {
            inner,
            writer,
            buffer,
            error: None,
        })
    }

    /// Writes buffered packets through to the underlying writer.
    ///
    /// Returns the first capture error if capturing has stopped.
    pub fn flush(&mut self) -> io::Result<()> {
        if let Some(err) = &self.error {
            return Err(io::Error::new(
                err.kind(),
                format!("pcap capture stopped: {err}"),
            ));
        }
        let result = lock(&self.buffer).flush();
        if let Err(err) = result {
            let report = io::Error::new(err.kind(), format!("pcap capture stopped: {err}"));
            self.error = Some(err);
            return Err(report);
        }
        Ok(())
    }

    /// The error that stopped the capture, if one did.
    pub fn capture_error(&self) -> Option<&io::Error> {
        self.error.as_ref()
    }

    /// The wrapped link.
    pub fn inner(&self) -> &L {
        &self.inner
    }

    /// The wrapped link, mutably (frames sent through it directly are not captured).
    pub fn inner_mut(&mut self) -> &mut L {
        &mut self.inner
    }

    /// Appends one frame, unless capturing has stopped.
    fn record(&mut self, frame: &[u8]) {
        if self.error.is_some() {
            return;
        }
        // A clock before 1970 is a broken clock; time 0 still keeps the packet readable.
        let timestamp = SystemTime::now()
            .duration_since(UNIX_EPOCH)
            .unwrap_or_default();
        // Frames are far shorter than 4 GiB; saturating keeps a bogus one from panicking.
        let orig_len = u32::try_from(frame.len()).unwrap_or(u32::MAX);
        let packet = PcapPacket::new(timestamp, orig_len, frame);
        if let Err(err) = self.writer.write_packet(&packet) {
            self.error = Some(into_io_error(err));
        }
    }
}

impl<L: Link, W: Write + Send> Link for PcapTap<L, W> {
    fn send(&mut self, frame: &[u8]) -> io::Result<()> {
        self.inner.send(frame)?;
        self.record(frame);
        Ok(())
    }

    fn recv(&mut self, buf: &mut [u8], wait: Wait) -> io::Result<Option<usize>> {
        let received = self.inner.recv(buf, wait)?;
        if let Some(len) = received {
            self.record(&buf[..len]);
        }
        Ok(received)
    }

    fn wait_fd(&self) -> Option<std::os::fd::BorrowedFd<'_>> {
        self.inner.wait_fd()
    }
}

impl<L: Link, W: Write + Send> Drop for PcapTap<L, W> {
    fn drop(&mut self) {
        // Nobody is left to hear about a failure here; `flush` is the way to check.
        if self.error.is_none() {
            let _ = lock(&self.buffer).flush();
        }
    }
}

/// The pcap writer's handle on the tap's buffered writer.
#[derive(Debug)]
struct SharedWriter<W: Write>(Arc<Mutex<BufWriter<W>>>);

impl<W: Write> Write for SharedWriter<W> {
    fn write(&mut self, bytes: &[u8]) -> io::Result<usize> {
        lock(&self.0).write(bytes)
    }

    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        lock(&self.0).write_all(bytes)
    }

    fn flush(&mut self) -> io::Result<()> {
        lock(&self.0).flush()
    }
}

fn lock<W: Write>(buffer: &Mutex<BufWriter<W>>) -> MutexGuard<'_, BufWriter<W>> {
    // A panic while writing leaves at worst a half-written packet; the capture is a
    // diagnostic, so carry on rather than poison the bus thread.
    buffer.lock().unwrap_or_else(PoisonError::into_inner)
}

fn into_io_error(err: PcapError) -> io::Error {
    match err {
        PcapError::IoError(err) => err,
        other => io::Error::other(other),
    }
}
