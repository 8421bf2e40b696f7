//! Reading a file the user names. A device (`/dev/zero`, a terminal) or a
//! socket has no end: reading one whole ran until memory did, and the
//! kernel killed the command. Such a path is refused before a byte is
//! read; a pipe is read, as a shell's `<(…)` hands one over, up to
//! [`MAX_BYTES`] (a pipe may have no end either: `<(yes 1,2,3)`). The path
//! `-` is standard input, as `cat run.csv | mckibben fit -` gives it.

use std::fs;
use std::io::{self, Read as _};
use std::path::Path;

/// The path that reads standard input.
pub const STANDARD_INPUT: &str = "-";

/// The most bytes a file may hold: a record of 10⁷ samples of a few
/// columns is under a gigabyte as text, and the file is held whole while
/// it is parsed.
pub const MAX_BYTES: u64 = 2 << 30;

/// The bytes of the file at `path`, or an error where `path` names a
/// device or a socket, or holds more than [`MAX_BYTES`] (a folder, a
/// missing file: the OS's own errors).
pub fn read(path: &Path) -> io::Result<Vec<u8>> {
    read_at_most(path, MAX_BYTES)
}

/// [`read`] as UTF-8 text.
pub fn read_to_string(path: &Path) -> io::Result<String> {
    String::from_utf8(read(path)?)
        .map_err(|e| io::Error::new(io::ErrorKind::InvalidData, format!("not UTF-8 text: {e}")))
}

fn read_at_most(path: &Path, limit: u64) -> io::Result<Vec<u8>> {
    let too_large = || {
        io::Error::new(
            io::ErrorKind::InvalidInput,
            format!(
                "more than {} bytes ({} GiB), more than a record holds: split it, or \
                 check that this is the file meant",
                limit,
                limit >> 30
            ),
        )
    };
    let mut bytes = Vec::new();
    if path == Path::new(STANDARD_INPUT) {
        use std::io::IsTerminal as _;
        if io::stdin().is_terminal() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "standard input is a terminal: pipe the file in (`cat run.csv | mckibben ...`)",
            ));
        }
        io::stdin().lock().take(limit + 1).read_to_end(&mut bytes)?;
    } else {
        refuse_endless(path)?;
        let file = fs::File::open(path)?;
        if file.metadata()?.len() > limit {
            return Err(too_large());
        }
        file.take(limit + 1).read_to_end(&mut bytes)?;
    }
    match bytes.len() as u64 > limit {
        true => Err(too_large()),
        false => Ok(bytes),
    }
}

fn refuse_endless(path: &Path) -> io::Result<()> {
    #[cfg(unix)]
    {
        use std::os::unix::fs::FileTypeExt as _;
        let kind = fs::metadata(path)?.file_type();
        if kind.is_char_device() || kind.is_block_device() || kind.is_socket() {
            return Err(io::Error::new(
                io::ErrorKind::InvalidInput,
                "a device or a socket, not a file: it has no end to read to",
            ));
        }
    }
    #[cfg(not(unix))]
    let _ = path;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[cfg(unix)]
    #[test]
    fn a_device_is_refused_and_a_file_or_a_pipe_is_read() {
        let e = read(Path::new("/dev/zero")).unwrap_err();
        assert_eq!(e.kind(), io::ErrorKind::InvalidInput, "{e}");
        assert!(e.to_string().contains("a device or a socket"), "{e}");
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.csv");
        fs::write(&file, "t,x\n").unwrap();
        assert_eq!(read_to_string(&file).unwrap(), "t,x\n");
        // A named pipe with a writer: read to its end.
        let fifo = dir.path().join("pipe");
        let made = std::process::Command::new("mkfifo").arg(&fifo).status();
        if made.is_ok_and(|s| s.success()) {
            let writer = {
                let fifo = fifo.clone();
                std::thread::spawn(move || fs::write(fifo, "t,x\n0,1\n").unwrap())
            };
            assert_eq!(read_to_string(&fifo).unwrap(), "t,x\n0,1\n");
            writer.join().unwrap();
        }
    }

    /// A file past the limit is refused, whether its size is known (a
    /// file) or only found by reading (a pipe).
    #[test]
    fn a_file_past_the_limit_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("a.csv");
        fs::write(&file, "t,x\n0,1\n").unwrap();
        assert_eq!(read_at_most(&file, 8).unwrap().len(), 8);
        let e = read_at_most(&file, 7).unwrap_err();
        assert!(e.to_string().starts_with("more than 7 bytes"), "{e}");
        #[cfg(unix)]
        {
            let fifo = dir.path().join("pipe");
            let made = std::process::Command::new("mkfifo").arg(&fifo).status();
            if made.is_ok_and(|s| s.success()) {
                let writer = {
                    let fifo = fifo.clone();
                    // The reader stops at the limit and closes the pipe.
                    std::thread::spawn(move || {
                        let _ = fs::write(fifo, "t,x\n".repeat(1000));
                    })
                };
                let e = read_at_most(&fifo, 100).unwrap_err();
                assert!(e.to_string().starts_with("more than 100 bytes"), "{e}");
                writer.join().unwrap();
            }
        }
    }
}
