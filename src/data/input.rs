//! Reading a file the user names. A device (`/dev/zero`, a terminal) or a
//! socket has no end: reading one whole ran until memory did (24 GB, then
//! the kernel killed the command). Such a path is refused before a byte is
//! read; a pipe is read, as a shell's `<(…)` hands one over.

use std::fs;
use std::io;
use std::path::Path;

/// The bytes of the file at `path`, or an error where `path` names a
/// device or a socket (a folder, a missing file: the OS's own errors).
pub fn read(path: &Path) -> io::Result<Vec<u8>> {
    refuse_endless(path)?;
    fs::read(path)
}

/// [`read`] as UTF-8 text.
pub fn read_to_string(path: &Path) -> io::Result<String> {
    refuse_endless(path)?;
    fs::read_to_string(path)
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
}
