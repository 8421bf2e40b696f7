//! Writes that never leave a half-written file behind: the bytes go to a
//! temporary file beside the target, which is then renamed over it.

use std::fs;
use std::io::{self, Write};
use std::path::Path;

/// Creates the folder `dir` and its parents, as `fs::create_dir_all`; where
/// a part of the path is a file, the error names it (the OS says "File
/// exists" or "Not a directory").
pub fn create_dir_all(dir: &Path) -> io::Result<()> {
    fs::create_dir_all(dir).map_err(|e| match dir.ancestors().find(|a| a.is_file()) {
        Some(file) if file == dir => {
            io::Error::other(format!("{} is a file, not a folder", dir.display()))
        }
        Some(file) => io::Error::other(format!(
            "{} is a file, so {} cannot be a folder",
            file.display(),
            dir.display()
        )),
        None => e,
    })
}

/// Writes `bytes` to `path` atomically, creating the parent folder if needed.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> io::Result<()> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    create_dir_all(dir)?;
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::other(format!("{} names no file", path.display())))?;
    let tmp = dir.join(format!(
        ".{}.tmp-{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    let result = (|| {
        let mut f = fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        fs::rename(&tmp, path)
    })();
    if result.is_err() {
        let _ = fs::remove_file(&tmp);
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_folder_through_a_file_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("notadir");
        fs::write(&file, "").unwrap();
        let err = write_atomic(&file.join("x.csv"), b"t\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("notadir is a file"), "{err}");
    }

    #[test]
    fn replaces_content_and_leaves_no_temporary() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("sub/out.txt");
        write_atomic(&p, b"one").unwrap();
        write_atomic(&p, b"two").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"two");
        assert_eq!(fs::read_dir(p.parent().unwrap()).unwrap().count(), 1);
    }
}
