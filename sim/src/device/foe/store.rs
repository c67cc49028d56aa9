//! The simulated slave's file system for FoE: names to bytes, with per-file password and
//! access flags, and a total capacity (what a slave's flash or RAM disk would hold).
//!
//! A [`FileStore`] is a shared handle (clones see the same files), so a test can keep one to
//! seed files before a transfer and inspect them after, while the FoE service that owns the
//! other clone sits inside an emulated ESC.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, MutexGuard};

use ecat_wire::foe::FoeError;

/// One file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct FoeFile {
    /// Contents.
    pub data: Vec<u8>,
    /// Password an RRQ/WRQ must carry; 0 = none required.
    pub password: u32,
    /// The master may read it (else 0x8002 on RRQ).
    pub readable: bool,
    /// The master may overwrite it (else 0x8002 on WRQ).
    pub writable: bool,
}

impl FoeFile {
    /// A readable, writable file without password.
    pub fn new(data: Vec<u8>) -> Self {
        FoeFile {
            data,
            password: 0,
            readable: true,
            writable: true,
        }
    }

    /// Protected by `password` (a wrong one answers 0x800A).
    pub fn with_password(mut self, password: u32) -> Self {
        self.password = password;
        self
    }

    /// Not writable by the master.
    pub fn read_only(mut self) -> Self {
        self.writable = false;
        self
    }

    /// Not readable by the master (e.g. a firmware slot).
    pub fn write_only(mut self) -> Self {
        self.readable = false;
        self
    }

    fn check_password(&self, password: u32) -> Result<(), FoeError> {
        if self.password != 0 && self.password != password {
            return Err(FoeError::NoRights);
        }
        Ok(())
    }
}

#[derive(Debug)]
struct Files {
    files: BTreeMap<Vec<u8>, FoeFile>,
    capacity: usize,
    create_on_write: bool,
    /// Write requests accepted (transfers started).
    write_requests: u64,
    /// Downloads stored.
    commits: u64,
}

impl Files {
    fn used(&self) -> usize {
        self.files.values().map(|f| f.data.len()).sum()
    }
}

/// The files of one simulated slave (a shared handle).
#[derive(Debug, Clone)]
pub struct FileStore {
    inner: Arc<Mutex<Files>>,
}

impl Default for FileStore {
    /// 1 MiB, new files created on write.
    fn default() -> Self {
        Self::new(1024 * 1024)
    }
}

impl FileStore {
    /// An empty store holding at most `capacity` bytes in all files together; a WRQ for a
    /// name that does not exist creates the file.
    pub fn new(capacity: usize) -> Self {
        FileStore {
            inner: Arc::new(Mutex::new(Files {
                files: BTreeMap::new(),
                capacity,
                create_on_write: true,
                write_requests: 0,
                commits: 0,
            })),
        }
    }

    /// Whether a WRQ may create a file that does not exist (if not: 0x8001).
    pub fn set_create_on_write(&self, create: bool) {
        self.lock().create_on_write = create;
    }

    fn lock(&self) -> MutexGuard<'_, Files> {
        // A test thread that panicked while holding the lock leaves consistent data.
        self.inner.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Adds or replaces a file; returns the file replaced.
    pub fn insert(&self, name: &str, file: FoeFile) -> Option<FoeFile> {
        self.lock().files.insert(name.as_bytes().to_vec(), file)
    }

    /// The file called `name`.
    pub fn get(&self, name: &str) -> Option<FoeFile> {
        self.lock().files.get(name.as_bytes()).cloned()
    }

    /// The contents of `name`.
    pub fn data(&self, name: &str) -> Option<Vec<u8>> {
        self.get(name).map(|f| f.data)
    }

    /// Removes `name`.
    pub fn remove(&self, name: &str) -> Option<FoeFile> {
        self.lock().files.remove(name.as_bytes())
    }

    /// The names of all files (non-UTF-8 bytes replaced).
    pub fn names(&self) -> Vec<String> {
        self.lock()
            .files
            .keys()
            .map(|k| String::from_utf8_lossy(k).into_owned())
            .collect()
    }

    /// Bytes used by all files.
    pub fn used(&self) -> usize {
        self.lock().used()
    }

    /// Write requests (WRQ) accepted so far: each starts a download (a test counts with it
    /// how often a file was written).
    pub fn write_requests(&self) -> u64 {
        self.lock().write_requests
    }

    /// Downloads completed and stored so far.
    pub fn commits(&self) -> u64 {
        self.lock().commits
    }

    /// Total capacity in bytes.
    pub fn capacity(&self) -> usize {
        self.lock().capacity
    }

    /// Opens `name` for an upload (RRQ): a snapshot of its contents.
    pub(crate) fn open_read(&self, name: &[u8], password: u32) -> Result<Vec<u8>, FoeError> {
        let files = self.lock();
        let file = files.files.get(name).ok_or(FoeError::NotFound)?;
        file.check_password(password)?;
        if !file.readable {
            return Err(FoeError::AccessDenied);
        }
        Ok(file.data.clone())
    }

    /// Opens `name` for a download (WRQ): the bytes it may grow to without overflowing the
    /// store (its current contents will be replaced, so they count as free).
    pub(crate) fn open_write(&self, name: &[u8], password: u32) -> Result<usize, FoeError> {
        let mut files = self.lock();
        let replaced = match files.files.get(name) {
            Some(file) => {
                file.check_password(password)?;
                if !file.writable {
                    return Err(FoeError::AccessDenied);
                }
                file.data.len()
            }
            None if files.create_on_write => 0,
            None => return Err(FoeError::NotFound),
        };
        files.write_requests += 1;
        Ok(files.capacity.saturating_sub(files.used() - replaced))
    }

    /// Stores the downloaded contents of `name`, keeping an existing file's flags.
    pub(crate) fn commit(&self, name: &[u8], data: Vec<u8>) {
        let mut files = self.lock();
        files.commits += 1;
        match files.files.get_mut(name) {
            Some(file) => file.data = data,
            None => {
                files.files.insert(name.to_vec(), FoeFile::new(data));
            }
        }
    }
}
