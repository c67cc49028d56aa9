//! One attached program: its socket's lines (docs/application.md, "The protocol"), its
//! eventfd, and its claim.

use std::os::fd::{AsFd, AsRawFd, FromRawFd, OwnedFd};
use std::sync::Arc;
use std::time::Duration;

use ecat_app::fd_passing;
use ecat_app::protocol::{Line, MAX_LINE, Request, VERSION};
use tokio::io::{AsyncReadExt, AsyncWriteExt, Interest};
use tokio::net::UnixStream;
use tokio::sync::mpsc;

use super::region::CommitRegion;
use super::{AppEvent, Inner, Peer};

/// Requests a program may send in one second before it is detached as flooding.
const REQUESTS_PER_SECOND: u32 = 100;
/// How long an answer may wait for the program to read: longer, and it is detached.
const SEND_TIMEOUT: Duration = Duration::from_secs(1);

/// Why a session ends early (logged).
type Detach = String;

/// A program's session until it closes, floods, or ecatd stops.
pub(super) async fn serve(
    mut stream: UnixStream,
    id: u64,
    peer: Peer,
    inner: Arc<Inner>,
    mut events: mpsc::Receiver<Line>,
) {
    let mut session = Session {
        id,
        peer,
        inner: Arc::clone(&inner),
        waker: None,
        writable: false,
        generation: None,
    };
    let result = session.run(&mut stream, &mut events).await;
    if let Err(reason) = &result {
        tracing::info!(session = id, pid = peer.pid, uid = peer.uid, %reason, "application detached");
    }
    session.end(result.is_ok());
}

struct Session {
    id: u64,
    peer: Peer,
    inner: Arc<Inner>,
    waker: Option<Arc<OwnedFd>>,
    writable: bool,
    /// The generation attached to (after HELLO).
    generation: Option<u32>,
}

impl Session {
    async fn run(
        &mut self,
        stream: &mut UnixStream,
        events: &mut mpsc::Receiver<Line>,
    ) -> Result<(), Detach> {
        let mut buf = [0u8; MAX_LINE];
        let mut filled = 0usize;
        let mut window = tokio::time::Instant::now();
        let mut requests = 0u32;
        loop {
            tokio::select! {
                read = stream.read(&mut buf[filled..]) => {
                    let read = read.map_err(|err| format!("read: {err}"))?;
                    if read == 0 {
                        return Ok(());
                    }
                    filled += read;
                    while let Some(end) = buf[..filled].iter().position(|&b| b == b'\n') {
                        if window.elapsed() >= Duration::from_secs(1) {
                            window = tokio::time::Instant::now();
                            requests = 0;
                        }
                        requests += 1;
                        if requests > REQUESTS_PER_SECOND {
                            let _ = send(stream, &Line::Refused("flooding: more than 100 requests a second".into()), &[]).await;
                            return Err("flooding".into());
                        }
                        let text = String::from_utf8_lossy(&buf[..end]).into_owned();
                        buf.copy_within(end + 1..filled, 0);
                        filled -= end + 1;
                        self.request(stream, &text).await?;
                    }
                    if filled == buf.len() {
                        let _ = send(stream, &Line::Refused(format!("line longer than {MAX_LINE} bytes")), &[]).await;
                        return Err("line too long".into());
                    }
                }
                event = events.recv() => {
                    let Some(line) = event else {
                        // ecatd is stopping and dropped the session's sender.
                        let _ = send(stream, &Line::Shutdown, &[]).await;
                        return Ok(());
                    };
                    send(stream, &line, &[]).await?;
                    if line == Line::Shutdown {
                        return Ok(());
                    }
                }
            }
        }
    }

    async fn request(&mut self, stream: &mut UnixStream, text: &str) -> Result<(), Detach> {
        let request = match Request::parse(text) {
            Ok(request) => request,
            Err(reason) => {
                let _ = send(stream, &Line::Refused(reason.clone()), &[]).await;
                return Err(reason);
            }
        };
        match (request, self.generation) {
            (Request::Hello { version, writable }, None) => {
                if version != VERSION {
                    let reason = format!(
                        "protocol version {version} not supported (ecatd speaks {VERSION})"
                    );
                    let _ = send(stream, &Line::Refused(reason.clone()), &[]).await;
                    return Err(reason);
                }
                self.hello(stream, writable).await
            }
            (Request::Hello { .. }, Some(_)) => {
                let _ = send(stream, &Line::Refused("already attached".into()), &[]).await;
                Err("HELLO twice".into())
            }
            (_, None) => {
                let _ = send(stream, &Line::Refused("HELLO first".into()), &[]).await;
                Err("request before HELLO".into())
            }
            (Request::Claim, Some(generation)) => self.claim(stream, generation).await,
            (Request::Release, Some(_)) => {
                if self.inner.share.release(self.id) {
                    self.inner.owner_gone(self.id, "released");
                }
                send(stream, &Line::Released, &[]).await
            }
            (Request::Ping, Some(_)) => send(stream, &Line::Pong, &[]).await,
        }
    }

    async fn hello(&mut self, stream: &mut UnixStream, writable: bool) -> Result<(), Detach> {
        let Some(region) = self.inner.share.region() else {
            let reason = "no process image yet (the segment is not scanned)".to_string();
            let _ = send(stream, &Line::Refused(reason.clone()), &[]).await;
            return Err(reason);
        };
        let waker = Arc::new(eventfd().map_err(|err| format!("eventfd: {err}"))?);
        let line = Line::Hello {
            generation: region.generation(),
            region_len: region.len(),
        };
        send(stream, &line, &[region.handout(), waker.as_fd()]).await?;
        self.inner.share.add_waker(Arc::clone(&waker));
        self.waker = Some(waker);
        self.writable = writable;
        self.generation = Some(region.generation());
        tracing::info!(
            session = self.id,
            pid = self.peer.pid,
            uid = self.peer.uid,
            gid = self.peer.gid,
            mode = if writable { "rw" } else { "ro" },
            generation = region.generation(),
            "application attached"
        );
        Ok(())
    }

    async fn claim(&mut self, stream: &mut UnixStream, generation: u32) -> Result<(), Detach> {
        if !self.writable {
            return send(stream, &Line::Refused("read-only attachment".into()), &[]).await;
        }
        let Some(region) = self
            .inner
            .share
            .region()
            .filter(|r| r.generation() == generation)
        else {
            return send(
                stream,
                &Line::Refused("layout changed: attach again".into()),
                &[],
            )
            .await;
        };
        let commits = match CommitRegion::create(generation, region.image_len()) {
            Ok(commits) => Arc::new(commits),
            Err(err) => {
                return send(
                    stream,
                    &Line::Refused(format!("cannot make the commit region: {err}")),
                    &[],
                )
                .await;
            }
        };
        if let Err(owner) = self.inner.share.claim(self.id, Arc::clone(&commits)) {
            let who = self.inner.peer_of(owner);
            let reason = match who {
                Some(p) => format!("owned pid={} uid={}", p.pid, p.uid),
                None => "owned".to_string(),
            };
            return send(stream, &Line::Refused(reason), &[]).await;
        }
        region.set_owner(self.peer.pid, self.peer.uid);
        let answer = send(
            stream,
            &Line::Claimed {
                region_len: commits.len(),
            },
            &[commits.handout()],
        )
        .await;
        if answer.is_err() {
            self.inner.share.release(self.id);
            return answer;
        }
        self.inner.publish(AppEvent::Claimed { peer: self.peer });
        tracing::info!(
            session = self.id,
            pid = self.peer.pid,
            uid = self.peer.uid,
            "application owns the outputs"
        );
        Ok(())
    }

    /// The session is over: no more wake-ups, and an owner's outputs go to the safe values.
    fn end(&mut self, clean: bool) {
        if let Some(waker) = self.waker.take() {
            self.inner.share.remove_waker(&waker);
        }
        if self.inner.share.release(self.id) {
            self.inner
                .owner_gone(self.id, if clean { "closed" } else { "detached" });
        }
        self.inner.forget(self.id);
    }
}

/// Sends `line` with `fds`, waiting at most [`SEND_TIMEOUT`] for the program to read.
async fn send(
    stream: &mut UnixStream,
    line: &Line,
    fds: &[std::os::fd::BorrowedFd<'_>],
) -> Result<(), Detach> {
    let text = format!("{line}\n");
    let bytes = text.as_bytes();
    let sent = tokio::time::timeout(SEND_TIMEOUT, async {
        loop {
            stream.writable().await?;
            match stream.try_io(Interest::WRITABLE, || {
                fd_passing::send(stream.as_fd(), bytes, fds)
            }) {
                Ok(sent) => return Ok(sent),
                Err(err) if err.kind() == std::io::ErrorKind::WouldBlock => continue,
                Err(err) => return Err(err),
            }
        }
    })
    .await
    .map_err(|_| "the program does not read its socket".to_string())?
    .map_err(|err| format!("send: {err}"))?;
    if sent < bytes.len() {
        tokio::time::timeout(SEND_TIMEOUT, stream.write_all(&bytes[sent..]))
            .await
            .map_err(|_| "the program does not read its socket".to_string())?
            .map_err(|err| format!("send: {err}"))?;
    }
    Ok(())
}

/// A non-blocking eventfd.
fn eventfd() -> std::io::Result<OwnedFd> {
    // SAFETY: plain flags; the result is checked.
    let fd = unsafe { libc::eventfd(0, libc::EFD_NONBLOCK | libc::EFD_CLOEXEC) };
    if fd < 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: just created, owned by nobody else.
    let fd = unsafe { OwnedFd::from_raw_fd(fd) };
    debug_assert!(fd.as_raw_fd() >= 0);
    Ok(fd)
}
