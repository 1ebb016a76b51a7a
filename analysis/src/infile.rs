//! The one way input files are read: `--eds`, `--config`, `--profile`, `extends =`,
//! `--lss-store`, `eds =` in a machine file, scenario files and `analyze` inputs.
//!
//! A file is opened without blocking (a FIFO with no writer does not hang the open), checked
//! with `fstat` on the descriptor opened (no race with a rename): only a regular file is read;
//! a FIFO, a device (`/dev/zero`), a directory or a socket is refused with a message naming
//! the file and what it is. Reading stops one byte past the caller's cap, so a file that
//! grows while it is read costs no more memory than the cap either. Text must be UTF-8; the
//! error says the line and column of the first byte that is not.

use std::fmt;
use std::io::Read;
use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
use std::path::{Path, PathBuf};

/// Cap for configuration files (machine, profile, EDS, LSS store), bytes: a vendor EDS is a
/// few hundred KiB; the EDS parser's own cap is 8 MiB.
pub const MAX_CONFIG_BYTES: u64 = 8 << 20;

/// What went wrong reading an input file.
#[derive(Debug)]
pub enum Problem {
    NotFound,
    /// Not a regular file: what it is ("a FIFO", "a character device", ...).
    NotRegular(&'static str),
    /// Larger than the cap: its size when `fstat` knew it, else `None` (it grew).
    TooLarge {
        cap: u64,
        size: Option<u64>,
    },
    /// Not UTF-8 at line, column (bytes, from 1).
    NotUtf8 {
        line: usize,
        column: usize,
    },
    Io(std::io::Error),
}

/// An input file that could not be read, with its path and the reason.
#[derive(Debug)]
pub struct InputError {
    pub path: PathBuf,
    /// What the file is for (`--eds`, `machine file`); empty: not said.
    pub what: &'static str,
    pub problem: Problem,
}

impl InputError {
    pub fn is_not_found(&self) -> bool {
        matches!(self.problem, Problem::NotFound)
    }
}

impl InputError {
    /// The reason alone, without the file's name.
    pub fn reason(&self) -> String {
        match &self.problem {
            Problem::NotFound => "cannot read: no such file".into(),
            Problem::NotRegular(kind) => {
                format!("{kind}, not a regular file: give a file (it is read whole)")
            }
            Problem::TooLarge { cap, size } => {
                let size = match size {
                    Some(s) => format!("{s} bytes"),
                    None => format!("more than {cap} bytes"),
                };
                format!("{size}, above the cap of {cap} bytes ({})", human(*cap))
            }
            Problem::NotUtf8 { line, column } => {
                format!("line {line}, column {column}: not UTF-8 text")
            }
            Problem::Io(e) => format!("cannot read: {e}"),
        }
    }
}

impl fmt::Display for InputError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let p = crate::quote::text(&self.path.to_string_lossy());
        if self.what.is_empty() {
            write!(f, "{p}: {}", self.reason())
        } else {
            write!(f, "{} {p}: {}", self.what, self.reason())
        }
    }
}

impl std::error::Error for InputError {}

fn human(bytes: u64) -> String {
    if bytes >= 1 << 20 && bytes.is_multiple_of(1 << 20) {
        format!("{} MiB", bytes >> 20)
    } else if bytes >= 1 << 10 && bytes.is_multiple_of(1 << 10) {
        format!("{} KiB", bytes >> 10)
    } else {
        format!("{bytes} bytes")
    }
}

/// What a file type is, for a message.
fn kind_name(t: std::fs::FileType) -> &'static str {
    if t.is_dir() {
        "a directory"
    } else if t.is_fifo() {
        "a FIFO"
    } else if t.is_char_device() {
        "a character device"
    } else if t.is_block_device() {
        "a block device"
    } else if t.is_socket() {
        "a socket"
    } else {
        "not a regular file"
    }
}

/// An input file opened for reading: a regular file, its size when opened.
pub struct Opened {
    pub file: std::fs::File,
    pub size: u64,
}

/// Open `path` for reading: without blocking, and only when `fstat` says regular file.
pub fn open(path: &Path, what: &'static str) -> Result<Opened, InputError> {
    let err = |problem| InputError {
        path: path.to_path_buf(),
        what,
        problem,
    };
    let file = std::fs::OpenOptions::new()
        .read(true)
        .custom_flags(libc::O_NONBLOCK | libc::O_NOCTTY | libc::O_CLOEXEC)
        .open(path)
        .map_err(|e| {
            err(if e.kind() == std::io::ErrorKind::NotFound {
                Problem::NotFound
            } else {
                Problem::Io(e)
            })
        })?;
    let m = file.metadata().map_err(|e| err(Problem::Io(e)))?;
    if !m.file_type().is_file() {
        return Err(err(Problem::NotRegular(kind_name(m.file_type()))));
    }
    // Back to blocking reads (no effect on a regular file, but said plainly).
    // SAFETY: fcntl on a descriptor this function owns.
    unsafe {
        use std::os::fd::AsRawFd;
        let fd = file.as_raw_fd();
        let fl = libc::fcntl(fd, libc::F_GETFL);
        if fl >= 0 {
            libc::fcntl(fd, libc::F_SETFL, fl & !libc::O_NONBLOCK);
        }
    }
    Ok(Opened {
        size: m.len(),
        file,
    })
}

/// The bytes of `path`, at most `cap` (see the module's documentation).
pub fn read_bytes(path: &Path, what: &'static str, cap: u64) -> Result<Vec<u8>, InputError> {
    let Opened { file, size } = open(path, what)?;
    let err = |problem| InputError {
        path: path.to_path_buf(),
        what,
        problem,
    };
    if size > cap {
        return Err(err(Problem::TooLarge {
            cap,
            size: Some(size),
        }));
    }
    let mut out = Vec::with_capacity(size as usize);
    file.take(cap + 1)
        .read_to_end(&mut out)
        .map_err(|e| err(Problem::Io(e)))?;
    if out.len() as u64 > cap {
        return Err(err(Problem::TooLarge { cap, size: None }));
    }
    Ok(out)
}

/// `bytes` as UTF-8 text, or where it is not.
pub fn utf8(bytes: Vec<u8>) -> Result<String, (usize, usize)> {
    String::from_utf8(bytes).map_err(|e| {
        let at = e.utf8_error().valid_up_to();
        crate::quote::line_col(e.as_bytes(), at)
    })
}

/// The text of `path`, at most `cap` bytes, UTF-8 (see the module's documentation).
pub fn read_text(path: &Path, what: &'static str, cap: u64) -> Result<String, InputError> {
    let b = read_bytes(path, what, cap)?;
    utf8(b).map_err(|(line, column)| InputError {
        path: path.to_path_buf(),
        what,
        problem: Problem::NotUtf8 { line, column },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scratch(name: &str) -> PathBuf {
        let d =
            std::env::temp_dir().join(format!("drive-emu-infile-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir(&d).unwrap();
        d
    }

    #[test]
    fn devices_fifos_and_directories_are_refused_by_name() {
        let d = scratch("kinds");
        let fifo = d.join("pipe");
        let c = std::ffi::CString::new(fifo.to_str().unwrap()).unwrap();
        // SAFETY: a valid C string.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        // No writer: a blocking open would hang here.
        let e = read_text(&fifo, "--eds", 1 << 20).unwrap_err().to_string();
        assert!(
            e.starts_with("--eds ") && e.contains("pipe: a FIFO, not a regular file"),
            "{e}"
        );
        let e = read_text(Path::new("/dev/zero"), "--config", 1 << 20)
            .unwrap_err()
            .to_string();
        assert!(e.contains("/dev/zero: a character device"), "{e}");
        let e = read_text(&d, "", 1 << 20).unwrap_err().to_string();
        assert!(e.contains("a directory"), "{e}");
        let e = read_text(&d.join("none"), "", 1).unwrap_err();
        assert!(e.is_not_found(), "{e}");
        // A symlink to a device is the device.
        let link = d.join("zero");
        std::os::unix::fs::symlink("/dev/zero", &link).unwrap();
        assert!(read_bytes(&link, "", 1 << 20)
            .unwrap_err()
            .to_string()
            .contains("a character device"));
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_file_over_the_cap_is_refused_before_it_is_read() {
        let d = scratch("cap");
        let f = d.join("big.toml");
        std::fs::write(&f, vec![b'#'; 1025]).unwrap();
        let e = read_text(&f, "--profile", 1024).unwrap_err().to_string();
        assert!(
            e.contains("1025 bytes, above the cap of 1024 bytes (1 KiB)"),
            "{e}"
        );
        assert_eq!(read_text(&f, "", 1025).unwrap().len(), 1025);
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn text_that_is_not_utf8_says_where() {
        let d = scratch("utf8");
        let f = d.join("m.toml");
        std::fs::write(&f, b"a = 1\nb = \"\xff\"\n").unwrap();
        let e = read_text(&f, "machine file", 1024).unwrap_err().to_string();
        assert!(e.ends_with("line 2, column 6: not UTF-8 text"), "{e}");
        std::fs::remove_dir_all(&d).unwrap();
    }

    #[test]
    fn a_path_with_control_characters_is_shown_escaped() {
        let e = read_text(Path::new("/nonexistent/\u{1b}[2Jx"), "", 1)
            .unwrap_err()
            .to_string();
        assert!(e.contains("\\u{1b}[2Jx") && !e.contains('\u{1b}'), "{e}");
    }
}
