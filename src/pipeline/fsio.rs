//! File-system helpers for the pipeline: every error names its path, files are created
//! mode 0644 and directories 0755 (reports and state are meant to be read by a web
//! server or a colleague), writes are atomic (temp file in the same directory, fsync,
//! rename), and advisory locks (`flock`: exclusive, shared or tried without waiting;
//! released when the process dies; a lock file is unlinked only by its exclusive holder,
//! and lockers check that the file they locked is still the one at the path).

use std::fs::{File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Mode of every file the pipeline writes.
pub const FILE_MODE: u32 = 0o644;
/// Mode of every directory the pipeline creates.
pub const DIR_MODE: u32 = 0o755;

/// Wrap an I/O error so its message names the operation and the path.
pub fn at(op: &str, path: &Path, e: io::Error) -> io::Error {
    io::Error::new(e.kind(), format!("{op} {}: {e}", path.display()))
}

/// `at` as a closure for `map_err`.
pub fn err_at<'a>(op: &'a str, path: &'a Path) -> impl FnOnce(io::Error) -> io::Error + 'a {
    move |e| at(op, path, e)
}

/// Set the permission bits of `path` (no-op off unix).
pub fn set_mode(path: &Path, mode: u32) -> io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        std::fs::set_permissions(path, std::fs::Permissions::from_mode(mode))
            .map_err(err_at("cannot set the permissions of", path))
    }
    #[cfg(not(unix))]
    {
        let _ = (path, mode);
        Ok(())
    }
}

/// `create_dir_all`, naming the path on error.
pub fn create_dir_all(path: &Path) -> io::Result<()> {
    std::fs::create_dir_all(path).map_err(err_at("cannot create the directory", path))
}

/// Read a file, naming the path on error.
pub fn read(path: &Path) -> io::Result<Vec<u8>> {
    std::fs::read(path).map_err(err_at("cannot read", path))
}

/// Write `bytes` to a new file `path` (which must not exist), fsynced, mode 0644.
pub fn write_new(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let mut f = File::create_new(path).map_err(err_at("cannot create", path))?;
    f.write_all(bytes).map_err(err_at("cannot write", path))?;
    f.sync_all().map_err(err_at("cannot sync", path))?;
    set_mode(path, FILE_MODE)
}

/// Write bytes to `path` atomically: a temp file in the same directory, fsync, mode
/// 0644, rename. Readers see the old content or the new one, never a mix.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    create_dir_all(dir)?;
    let mut tmp = tempfile::NamedTempFile::new_in(dir).map_err(err_at("cannot create a temp file in", dir))?;
    tmp.write_all(bytes)
        .map_err(err_at("cannot write a temp file for", path))?;
    tmp.as_file()
        .sync_all()
        .map_err(err_at("cannot sync a temp file for", path))?;
    set_mode(tmp.path(), FILE_MODE)?;
    tmp.persist(path).map_err(|e| at("cannot replace", path, e.error))?;
    Ok(())
}

/// A held advisory lock; released on drop (or when the process dies).
///
/// Lock files may be unlinked, but only by a holder of the exclusive lock
/// ([`Lock::unlink`]); every locker checks after acquiring that the file it locked is
/// still the one at the path, and starts again otherwise. So an unlinked lock file never
/// splits the lockers of one path into two groups that exclude nobody.
#[derive(Debug)]
pub struct Lock {
    _file: File,
    path: PathBuf,
}

impl Lock {
    /// Remove the lock file while holding it (exclusive holders only), then release it.
    /// A process waiting on the old file sees, once it acquires it, that the path no
    /// longer names it and locks the path anew.
    pub fn unlink(self) -> io::Result<()> {
        match std::fs::remove_file(&self.path) {
            Ok(()) => Ok(()),
            Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
            Err(e) => Err(at("cannot remove the lock file", &self.path, e)),
        }
    }
}

/// How to take a lock.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Mode {
    Exclusive,
    Shared,
    TryExclusive,
}

/// Take the exclusive advisory lock `path` (created if needed), waiting for it.
pub fn lock(path: &Path) -> io::Result<Lock> {
    Ok(take(path, Mode::Exclusive)?.expect("a blocking lock is always taken"))
}

/// Take the shared advisory lock `path` (created if needed), waiting while an exclusive
/// holder has it. Shared holders do not exclude one another.
pub fn lock_shared(path: &Path) -> io::Result<Lock> {
    Ok(take(path, Mode::Shared)?.expect("a blocking lock is always taken"))
}

/// Take the exclusive advisory lock `path` if nobody holds it (shared or exclusive);
/// `None` when someone does. Never waits.
pub fn try_lock(path: &Path) -> io::Result<Option<Lock>> {
    take(path, Mode::TryExclusive)
}

fn take(path: &Path, mode: Mode) -> io::Result<Option<Lock>> {
    // Each retry means an exclusive holder unlinked the file we locked (or the directory
    // we were about to create it in) in between; that happens a handful of times at most.
    for _ in 0..1000 {
        if let Some(d) = path.parent() {
            create_dir_all(d)?;
        }
        let f = match OpenOptions::new().create(true).truncate(false).write(true).open(path) {
            Ok(f) => f,
            Err(e) if e.kind() == io::ErrorKind::NotFound => continue, // directory removed meanwhile
            Err(e) => return Err(at("cannot open the lock file", path, e)),
        };
        match mode {
            Mode::Exclusive => f.lock().map_err(err_at("cannot lock", path))?,
            Mode::Shared => f.lock_shared().map_err(err_at("cannot lock", path))?,
            Mode::TryExclusive => match f.try_lock() {
                Ok(()) => {}
                Err(std::fs::TryLockError::WouldBlock) => return Ok(None),
                Err(std::fs::TryLockError::Error(e)) => return Err(at("cannot lock", path, e)),
            },
        }
        if same_file(&f, path) {
            return Ok(Some(Lock {
                _file: f,
                path: path.to_path_buf(),
            }));
        }
    }
    Err(at(
        "cannot lock",
        path,
        io::Error::other("the lock file kept being removed and re-created"),
    ))
}

/// Is the open file `f` the file now at `path`?
fn same_file(f: &File, path: &Path) -> bool {
    #[cfg(unix)]
    {
        use std::os::unix::fs::MetadataExt;
        match (f.metadata(), std::fs::metadata(path)) {
            (Ok(a), Ok(b)) => a.dev() == b.dev() && a.ino() == b.ino(),
            _ => false,
        }
    }
    #[cfg(not(unix))]
    {
        let _ = f;
        path.exists()
    }
}

/// Remove a directory tree without ever leaving it half-deleted under its name: rename
/// it to a unique `.trash-*` sibling first, then delete that.
pub fn discard_dir(dir: &Path) -> io::Result<()> {
    let parent = dir.parent().unwrap_or(Path::new("."));
    let name = dir
        .file_name()
        .map(|n| n.to_string_lossy().to_string())
        .unwrap_or_default();
    let trash: PathBuf = parent.join(format!(".trash-{name}-{}-{}", std::process::id(), unique()));
    match std::fs::rename(dir, &trash) {
        Ok(()) => std::fs::remove_dir_all(&trash).map_err(err_at("cannot remove", &trash)),
        Err(e) if e.kind() == io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(at("cannot move aside", dir, e)),
    }
}

/// A process-unique counter (for temp names).
pub fn unique() -> u64 {
    use std::sync::atomic::{AtomicU64, Ordering};
    static N: AtomicU64 = AtomicU64::new(0);
    let t = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| d.subsec_nanos() as u64)
        .unwrap_or(0);
    (N.fetch_add(1, Ordering::Relaxed) << 32) ^ t
}

/// Is `path` older than `age` (by modification time)? Unknown ages count as not old.
pub fn older_than(path: &Path, age: std::time::Duration) -> bool {
    std::fs::symlink_metadata(path)
        .and_then(|m| m.modified())
        .ok()
        .and_then(|t| t.elapsed().ok())
        .is_some_and(|e| e > age)
}
