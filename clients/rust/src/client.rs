//! [`App`]: one attachment to ecatd.

use std::io::Write;
use std::os::fd::{AsFd, AsRawFd, OwnedFd};
use std::os::unix::net::UnixStream;
use std::path::Path;
use std::time::{Duration, Instant};

use crate::entry::{Direction, Entry};
use crate::error::Error;
use crate::fd_passing;
use crate::protocol::{Line, MAX_LINE, Request, VERSION};
use crate::shm::{
    self, COMMIT_MAGIC, CommitShape, ENTRY_SIZE, FLAG_LIVE, FLAG_STALE, IMAGE_MAGIC, Mapping,
    commit, image,
};

/// How long a request's answer may take.
const ANSWER_TIMEOUT: Duration = Duration::from_secs(5);

/// A control program attached to ecatd: the layout, the last cycle's image, and (once
/// claimed) the outputs.
///
/// [`App::wait`] copies a whole cycle into the attachment's own buffers, so every
/// [`App::read`] until the next wait sees that one cycle. Nothing is allocated per cycle:
/// the buffers are sized at attach and entries are looked up once with [`App::entry`].
#[derive(Debug)]
pub struct App {
    socket: UnixStream,
    events: OwnedFd,
    image: Mapping,
    generation: u32,
    image_len: usize,
    slots: usize,
    stride: usize,
    entries: Vec<Entry>,
    /// The last cycle returned by `wait`, when ecatd published it, its inputs and
    /// outputs as sent.
    cycle: u64,
    published_ns: u64,
    inputs: Vec<u8>,
    sent: Vec<u8>,
    /// Where a cycle is copied before it is known whole (then swapped in).
    spare_inputs: Vec<u8>,
    spare_sent: Vec<u8>,
    /// The outputs this program will commit.
    outputs: Vec<u8>,
    commits: Option<Commits>,
    /// Bytes read from the socket that are not a whole line yet.
    pending: Vec<u8>,
    /// Once set, every further wait fails with it (the region is stale or ecatd is gone).
    ended: Option<Ended>,
}

#[derive(Debug)]
struct Commits {
    region: Mapping,
    stride: usize,
    last: u64,
}

#[derive(Debug, Clone, Copy)]
enum Ended {
    Layout(u32),
    Closed,
}

impl App {
    /// Attaches to the socket at `path` (`None`: [`crate::default_socket`]); `read_only`
    /// attaches a monitor that can never claim.
    pub fn connect(path: Option<&Path>, read_only: bool) -> Result<App, Error> {
        let path = path.map_or_else(crate::default_socket, Path::to_path_buf);
        let socket = UnixStream::connect(&path).map_err(|err| {
            Error::Io(std::io::Error::new(
                err.kind(),
                format!("cannot attach to {}: {err}", path.display()),
            ))
        })?;
        // An answer not back in this long means ecatd is stuck; `wait` uses its own timeout.
        socket.set_read_timeout(Some(ANSWER_TIMEOUT))?;
        let mut pending = Vec::with_capacity(4 * MAX_LINE);
        send(
            &socket,
            Request::Hello {
                version: VERSION,
                writable: !read_only,
            },
        )?;
        let mut fds = Vec::new();
        let line = answer(&socket, &mut pending, &mut fds)?;
        let Line::Hello {
            generation,
            region_len,
        } = line
        else {
            return Err(refusal(line));
        };
        let [region, events]: [OwnedFd; 2] = fds
            .try_into()
            .map_err(|_| Error::Protocol("HELLO without its two descriptors".into()))?;
        let image = Mapping::map(region.as_fd(), region_len, false)?;
        let mut magic = [0u8; 8];
        image.read_bytes(image::MAGIC, &mut magic);
        if magic != IMAGE_MAGIC || image.load_u32(image::VERSION) != shm::VERSION {
            return Err(Error::Protocol(
                "not an image region of layout version 1".into(),
            ));
        }
        let image_len = image.load_u32(image::IMAGE_LEN) as usize;
        let count = image.load_u32(image::ENTRY_COUNT) as usize;
        let table = image.load_u32(image::ENTRIES) as usize;
        if image.load_u32(image::ENTRY_SIZE) as usize != ENTRY_SIZE {
            return Err(Error::Protocol("entry size is not 64".into()));
        }
        let mut entries = Vec::with_capacity(count);
        for i in 0..count {
            let mut record = [0u8; ENTRY_SIZE];
            if !image.read_bytes(table + i * ENTRY_SIZE, &mut record) {
                return Err(Error::Protocol("entry table beyond the region".into()));
            }
            let entry = Entry::decode(&record)
                .filter(|e| e.lies_in(image_len))
                .ok_or_else(|| Error::Protocol(format!("entry {i} is malformed")))?;
            entries.push(entry);
        }
        let slots = image.load_u32(image::SLOTS) as usize;
        let stride = image.load_u32(image::SLOT_STRIDE) as usize;
        let shape = shm::ImageShape {
            image_len,
            entries: count,
        };
        if slots != shape.slots() || stride != shape.stride() || shape.len() > image.len() {
            return Err(Error::Protocol("slots do not match the image size".into()));
        }
        let mut app = App {
            socket,
            events,
            image,
            generation,
            image_len,
            slots,
            stride,
            entries,
            cycle: 0,
            published_ns: 0,
            inputs: vec![0; image_len],
            sent: vec![0; image_len],
            spare_inputs: vec![0; image_len],
            spare_sent: vec![0; image_len],
            outputs: vec![0; image_len],
            commits: None,
            pending,
            ended: None,
        };
        // Start from the newest cycle, so the first `read` sees real values.
        app.copy_newest();
        Ok(app)
    }

    /// Every mapped entry of this layout generation, in image order.
    pub fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// The layout generation this attachment reads.
    pub fn generation(&self) -> u32 {
        self.generation
    }

    /// The cycle period ecatd runs.
    pub fn period(&self) -> Duration {
        Duration::from_nanos(self.image.load_u64(image::PERIOD_NS))
    }

    /// The entry `index:subindex` of the slave at ring position `slave`.
    pub fn entry(&self, slave: u16, index: u16, subindex: u8) -> Result<Entry, Error> {
        self.entries
            .iter()
            .find(|e| e.position == slave && e.index == index && e.subindex == subindex)
            .cloned()
            .ok_or(Error::NoSuchEntry {
                slave,
                index,
                subindex,
            })
    }

    /// Takes the outputs. Refused (with the owner's pid and uid) while another program
    /// owns them; from now on this program's commits are what the cycle sends.
    pub fn claim(&mut self) -> Result<(), Error> {
        self.check_ended()?;
        send(&self.socket, Request::Claim)?;
        let mut fds = Vec::new();
        let line = self.answer(&mut fds)?;
        let Line::Claimed { region_len } = line else {
            return Err(refusal(line));
        };
        let [fd]: [OwnedFd; 1] = fds
            .try_into()
            .map_err(|_| Error::Protocol("CLAIM without its descriptor".into()))?;
        let region = Mapping::map(fd.as_fd(), region_len, true)?;
        let mut magic = [0u8; 8];
        region.read_bytes(commit::MAGIC, &mut magic);
        let shape = CommitShape {
            image_len: self.image_len,
        };
        if magic != COMMIT_MAGIC
            || region.load_u32(commit::GENERATION) != self.generation
            || region.load_u32(commit::IMAGE_LEN) as usize != self.image_len
            || region.load_u32(commit::SLOT_STRIDE) as usize != shape.stride()
            || shape.len() > region.len()
        {
            return Err(Error::Protocol(
                "the commit region does not match the layout".into(),
            ));
        }
        // Outputs this program does not write keep what the cycle sends now.
        self.outputs.copy_from_slice(&self.sent);
        self.commits = Some(Commits {
            last: region.load_u64(commit::COMMIT),
            stride: shape.stride(),
            region,
        });
        Ok(())
    }

    /// Gives the outputs back (the safe outputs go out from the next cycle).
    pub fn release(&mut self) -> Result<(), Error> {
        if self.commits.take().is_none() {
            return Ok(());
        }
        send(&self.socket, Request::Release)?;
        let line = self.answer(&mut Vec::new())?;
        match line {
            Line::Released => Ok(()),
            other => Err(refusal(other)),
        }
    }

    /// Whether this program owns the outputs.
    pub fn owns(&self) -> bool {
        self.commits.is_some()
    }

    /// Blocks until a cycle newer than the last one returned has completed (at once if one
    /// already has), copies its image and returns its number. Fails on timeout, when the
    /// layout changed, when the watchdog took the outputs, or when ecatd is gone.
    pub fn wait(&mut self, timeout: Duration) -> Result<u64, Error> {
        let deadline = Instant::now() + timeout;
        loop {
            self.check_ended()?;
            let flags = self.image.load_u32(image::FLAGS);
            if flags & FLAG_STALE != 0 {
                let generation = self.generation + 1;
                self.ended = Some(Ended::Layout(generation));
                self.commits = None;
                return Err(Error::LayoutChanged(generation));
            }
            if flags & FLAG_LIVE == 0 {
                // ecatd stopped publishing (it is shutting down).
                self.ended = Some(Ended::Closed);
                self.commits = None;
                return Err(Error::Closed);
            }
            if self.image.load_u64(image::CYCLE) > self.cycle && self.copy_newest() {
                return Ok(self.cycle);
            }
            let now = Instant::now();
            if now >= deadline {
                return Err(Error::Timeout);
            }
            let left = (deadline - now).as_millis().clamp(1, i32::MAX as u128) as i32;
            let mut polls = [
                libc::pollfd {
                    fd: self.events.as_raw_fd(),
                    events: libc::POLLIN,
                    revents: 0,
                },
                libc::pollfd {
                    fd: self.socket.as_raw_fd(),
                    events: libc::POLLIN,
                    revents: 0,
                },
            ];
            // SAFETY: two valid pollfd entries for the call.
            let ready = unsafe { libc::poll(polls.as_mut_ptr(), 2, left) };
            if ready < 0 {
                let err = std::io::Error::last_os_error();
                if err.kind() == std::io::ErrorKind::Interrupted {
                    continue;
                }
                return Err(err.into());
            }
            if polls[0].revents != 0 {
                let mut count = [0u8; 8];
                // Non-blocking: another thread may have read it first (EAGAIN).
                // SAFETY: reads 8 bytes into a live buffer.
                unsafe { libc::read(self.events.as_raw_fd(), count.as_mut_ptr().cast(), 8) };
            }
            if polls[1].revents != 0 {
                self.read_events()?;
            }
        }
    }

    /// The last cycle returned by [`App::wait`] (0 before the first).
    pub fn cycle(&self) -> u64 {
        self.cycle
    }

    /// When ecatd published the last cycle returned by [`App::wait`]: `CLOCK_MONOTONIC` in
    /// nanoseconds, the clock every process on this machine shares, so
    /// `clock_gettime(CLOCK_MONOTONIC)` right after the wait minus this is the wake-up
    /// latency. Copied with the cycle (one consistent slot). 0 before the first cycle, or
    /// from an ecatd that does not write it.
    pub fn published_ns(&self) -> u64 {
        self.published_ns
    }

    /// The value of `entry` in the last cycle (sign-extended for signed types): an input as
    /// received, an output as this program will commit it when it owns the outputs, else
    /// as the cycle sent it.
    pub fn read(&self, entry: &Entry) -> i64 {
        match entry.direction {
            Direction::In => entry.get_i64(&self.inputs),
            Direction::Out if self.commits.is_some() => entry.get_i64(&self.outputs),
            Direction::Out => entry.get_i64(&self.sent),
        }
    }

    /// The raw bits of `entry` in the last cycle as received (inputs) or sent (outputs).
    pub fn read_raw(&self, entry: &Entry) -> u64 {
        match entry.direction {
            Direction::In => entry.get(&self.inputs),
            Direction::Out => entry.get(&self.sent),
        }
    }

    /// Sets output `entry` to `value` for the next [`App::commit`].
    pub fn write(&mut self, entry: &Entry, value: i64) -> Result<(), Error> {
        if entry.direction != Direction::Out {
            return Err(Error::NotOutput);
        }
        if !entry.accepts(value) {
            return Err(Error::OutOfRange(value));
        }
        if !entry.set(&mut self.outputs, value as u64) {
            return Err(Error::OutOfRange(value));
        }
        Ok(())
    }

    /// Hands ecatd every output written so far, as one whole: the next cycle's frame
    /// carries all of them.
    pub fn commit(&mut self) -> Result<(), Error> {
        self.check_ended()?;
        let commits = self.commits.as_mut().ok_or(Error::NotOwner)?;
        let number = commits.last + 1;
        let slot = shm::slot_of(commit::FIRST_SLOT, commits.stride, number);
        shm::write_slot(
            &commits.region,
            slot,
            number,
            &[(shm::SLOT_HEADER, &self.outputs)],
        );
        commits.region.store_u64(commit::COMMIT, number);
        commits.last = number;
        Ok(())
    }

    /// The commit number the last frame carried (0: none of this layout yet).
    pub fn applied(&self) -> u64 {
        self.image.load_u64(image::APPLIED)
    }

    /// Detaches (an owner's outputs go to their safe values from the next cycle).
    pub fn close(self) {}

    /// Copies the newest published cycle into the buffers; false if it was overwritten
    /// while copying (the caller tries again).
    fn copy_newest(&mut self) -> bool {
        let cycle = self.image.load_u64(image::CYCLE);
        if cycle == 0 {
            return false;
        }
        let slot = shm::slot_of(self.slots, self.stride, cycle);
        let shape = shm::ImageShape {
            image_len: self.image_len,
            entries: self.entries.len(),
        };
        let (inputs, sent) = (&mut self.spare_inputs, &mut self.spare_sent);
        let mut published = [0u8; 8];
        let whole = shm::read_slot(&self.image, slot, cycle, |m| {
            m.read_bytes(slot + shm::slot::PUBLISHED_NS, &mut published);
            m.read_bytes(slot + shape.inputs_at(), inputs);
            m.read_bytes(slot + shape.outputs_at(), sent);
        });
        if whole {
            // A torn copy never reaches `read`: the last whole cycle stays until then.
            std::mem::swap(&mut self.inputs, &mut self.spare_inputs);
            std::mem::swap(&mut self.sent, &mut self.spare_sent);
            self.cycle = cycle;
            self.published_ns = u64::from_le_bytes(published);
        }
        whole
    }

    fn check_ended(&self) -> Result<(), Error> {
        match self.ended {
            Some(Ended::Layout(generation)) => Err(Error::LayoutChanged(generation)),
            Some(Ended::Closed) => Err(Error::Closed),
            None => Ok(()),
        }
    }

    /// Reads the event lines waiting on the socket; the first that ends something is
    /// returned as an error.
    fn read_events(&mut self) -> Result<(), Error> {
        let mut fds = Vec::new();
        let read = fill(&self.socket, &mut self.pending, &mut fds);
        let mut result = Ok(());
        while let Some(line) = take_line(&mut self.pending) {
            let line = line?;
            if let Err(err) = self.event(line) {
                result = result.and(Err(err));
            }
        }
        match read {
            Ok(0) => {
                self.ended = Some(Ended::Closed);
                self.commits = None;
                result.and(Err(Error::Closed))
            }
            Ok(_) => result,
            Err(err) => result.and(Err(err)),
        }
    }

    fn event(&mut self, line: Line) -> Result<(), Error> {
        match line {
            Line::LayoutChanged(generation) => {
                self.ended = Some(Ended::Layout(generation));
                self.commits = None;
                Err(Error::LayoutChanged(generation))
            }
            Line::Watchdog => {
                self.commits = None;
                Err(Error::Watchdog)
            }
            Line::Shutdown => {
                self.ended = Some(Ended::Closed);
                self.commits = None;
                Err(Error::Closed)
            }
            other => Err(Error::Protocol(format!("unexpected line {other}"))),
        }
    }

    /// The answer to the request just sent; events before it are taken as they come.
    fn answer(&mut self, fds: &mut Vec<OwnedFd>) -> Result<Line, Error> {
        loop {
            let line = answer(&self.socket, &mut self.pending, fds)?;
            if !line.is_event() {
                return Ok(line);
            }
            // A watchdog event before the answer still ends the ownership.
            let _ = self.event(line);
            self.check_ended()?;
        }
    }
}

fn send(socket: &UnixStream, request: Request) -> Result<(), Error> {
    let mut line = [0u8; MAX_LINE];
    let mut cursor = std::io::Cursor::new(&mut line[..]);
    writeln!(cursor, "{request}")?;
    let len = cursor.position() as usize;
    (&*socket).write_all(&line[..len])?;
    Ok(())
}

fn refusal(line: Line) -> Error {
    match line {
        Line::Refused(reason) => Error::Refused(reason),
        other => Error::Protocol(format!("unexpected answer {other}")),
    }
}

/// Reads more bytes (with their descriptors) into `pending`.
fn fill(
    socket: &UnixStream,
    pending: &mut Vec<u8>,
    fds: &mut Vec<OwnedFd>,
) -> Result<usize, Error> {
    let mut chunk = [0u8; MAX_LINE];
    let read = fd_passing::recv(socket.as_fd(), &mut chunk, fds)?;
    pending.extend_from_slice(&chunk[..read]);
    if pending.len() > 4 * MAX_LINE {
        return Err(Error::Protocol("a line from ecatd is too long".into()));
    }
    Ok(read)
}

/// The first whole line in `pending`, taken out of it.
fn take_line(pending: &mut Vec<u8>) -> Option<Result<Line, Error>> {
    let end = pending.iter().position(|&b| b == b'\n')?;
    let line: Vec<u8> = pending.drain(..=end).collect();
    let text = String::from_utf8_lossy(&line[..end]);
    Some(Line::parse(&text).map_err(Error::Protocol))
}

/// The next line from ecatd, reading as needed.
fn answer(
    socket: &UnixStream,
    pending: &mut Vec<u8>,
    fds: &mut Vec<OwnedFd>,
) -> Result<Line, Error> {
    loop {
        if let Some(line) = take_line(pending) {
            return line;
        }
        if fill(socket, pending, fds)? == 0 {
            return Err(Error::Closed);
        }
    }
}
