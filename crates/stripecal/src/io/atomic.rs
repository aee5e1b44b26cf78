//! Atomic file writes and checked file reads.
//!
//! [`write_atomic`] writes a temporary file next to the target, flushes it to disk and
//! renames it over the target, so a reader (or a crash) never sees a half-written file.

use std::fs::{self, File, OpenOptions};
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use crate::error::{Error, Result};

/// Distinguishes temporary files of concurrent writes from one process.
static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// How many temporary names are tried before giving up (a name can only be taken by a
/// stale file of an earlier process with the same pid).
const TMP_ATTEMPTS: usize = 16;

/// Writes `bytes` to `path` atomically: a temporary file `.{name}.tmp-{pid}-{n}` is
/// created in the target's folder, written, synced (`fsync`) and renamed over the
/// target. On any error the temporary file is removed and [`Error::Io`] names the
/// target. The target's folder must exist (it is not created).
pub fn write_atomic(path: impl AsRef<Path>, bytes: &[u8]) -> Result<()> {
    let path = path.as_ref();
    let Some(name) = path.file_name() else {
        return Err(Error::io(
            path,
            io::Error::new(io::ErrorKind::InvalidInput, "path does not name a file"),
        ));
    };
    let parent = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    if !parent.is_dir() {
        return Err(Error::io(
            path,
            io::Error::new(
                io::ErrorKind::NotFound,
                format!("folder {} does not exist", parent.display()),
            ),
        ));
    }

    let (tmp_path, file) = create_temp(parent, &name.to_string_lossy()).map_err(|e| {
        Error::io(
            path,
            io::Error::new(e.kind(), format!("cannot create a temporary file: {e}")),
        )
    })?;
    let result = write_sync(file, bytes).and_then(|()| fs::rename(&tmp_path, path));
    if let Err(e) = result {
        // Best effort: the original error is the one worth reporting.
        let _ = fs::remove_file(&tmp_path);
        return Err(Error::io(path, e));
    }
    sync_dir(parent);
    Ok(())
}

fn create_temp(dir: &Path, name: &str) -> io::Result<(PathBuf, File)> {
    let pid = std::process::id();
    let mut last_err = None;
    for _ in 0..TMP_ATTEMPTS {
        let n = TMP_COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = dir.join(format!(".{name}.tmp-{pid}-{n}"));
        match OpenOptions::new().write(true).create_new(true).open(&tmp) {
            Ok(f) => return Ok((tmp, f)),
            Err(e) if e.kind() == io::ErrorKind::AlreadyExists => last_err = Some(e),
            Err(e) => return Err(e),
        }
    }
    Err(last_err
        .unwrap_or_else(|| io::Error::new(io::ErrorKind::AlreadyExists, "no free name found")))
}

fn write_sync(mut file: File, bytes: &[u8]) -> io::Result<()> {
    file.write_all(bytes)?;
    file.sync_all()
}

/// Makes the rename durable on Unix (syncs the folder entry); best effort elsewhere.
fn sync_dir(dir: &Path) {
    #[cfg(unix)]
    {
        if let Ok(d) = File::open(dir) {
            let _ = d.sync_all();
        }
    }
    #[cfg(not(unix))]
    {
        let _ = dir;
    }
}

/// Why `path` cannot be read as a regular file, or `None` when it can be opened as one:
/// the error to report (the operating system's own when it has one, so its kind and
/// number stay) and a sentence that completes "`path` ...": it does not exist, is a
/// folder, a FIFO (reading it would wait for a writer), a device (`/dev/zero` never
/// ends), a socket, or a symbolic link that cannot be followed (a loop, or one pointing
/// nowhere).
pub fn file_problem(path: &Path) -> Option<(io::Error, String)> {
    match fs::metadata(path) {
        Ok(m) if m.is_file() => None,
        Ok(m) if m.is_dir() => {
            let why = "is a folder, not a file";
            Some((io::Error::new(io::ErrorKind::IsADirectory, why), why.into()))
        }
        Ok(m) => {
            let why = format!("is {}, not a regular file", special_kind(&m.file_type()));
            Some((
                io::Error::new(io::ErrorKind::InvalidInput, why.clone()),
                why,
            ))
        }
        Err(e) => {
            let link = fs::symlink_metadata(path).is_ok_and(|m| m.file_type().is_symlink());
            let why = if link {
                format!(
                    "is a symbolic link that cannot be followed (a loop, or it points to \
                     nothing): {e}"
                )
            } else if e.kind() == io::ErrorKind::NotFound {
                "does not exist".into()
            } else {
                format!("cannot be accessed: {e}")
            };
            Some((e, why))
        }
    }
}

/// What a file that is neither a regular file nor a folder is.
fn special_kind(t: &fs::FileType) -> &'static str {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt;
        if t.is_fifo() {
            return "a FIFO (named pipe)";
        }
        if t.is_char_device() {
            return "a character device (such as /dev/zero)";
        }
        if t.is_block_device() {
            return "a block device";
        }
        if t.is_socket() {
            return "a socket";
        }
    }
    let _ = t;
    "a special file"
}

/// [`Error::Io`] naming `path` when it is not a regular file that can be opened
/// ([`file_problem`]): checked before opening, so that a FIFO or a device never blocks
/// or floods a reader.
pub(super) fn check_regular(path: &Path) -> Result<()> {
    match file_problem(path) {
        None => Ok(()),
        // a missing file keeps the system's error (Python's FileNotFoundError)
        Some((e, why)) if why == "does not exist" => Err(Error::io(path, e)),
        Some((e, why)) => Err(Error::io(path, io::Error::new(e.kind(), why))),
    }
}

/// Reads a whole text file: [`Error::Io`] when it cannot be read (or is not a regular
/// file, [`check_regular`]), [`Error::Format`] (naming the line) when it is not UTF-8.
/// A leading UTF-8 byte-order mark is dropped.
pub(super) fn read_text(path: &Path) -> Result<String> {
    check_regular(path)?;
    let bytes = fs::read(path).map_err(|e| Error::io(path, e))?;
    match String::from_utf8(bytes) {
        Ok(mut s) => {
            if s.starts_with('\u{feff}') {
                s.drain(..'\u{feff}'.len_utf8());
            }
            Ok(s)
        }
        Err(e) => {
            let at = e.utf8_error().valid_up_to();
            let line = 1 + e.as_bytes()[..at].iter().filter(|&&b| b == b'\n').count();
            Err(Error::format(
                path,
                format!("line {line}"),
                format!("not valid UTF-8 text (byte offset {at})"),
            ))
        }
    }
}
