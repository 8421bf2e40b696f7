//! Writes that never leave a half-written file behind: the bytes go to a
//! temporary file beside the target, which is then renamed over it.

use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

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
    let tmp = stage(path, bytes)?;
    fs::rename(&tmp, path).inspect_err(|_| {
        let _ = fs::remove_file(&tmp);
    })
}

/// Writes every file of `files` or none: each goes first to a temporary
/// file beside its target, and only once all are written (and no target is
/// a folder) are they renamed over their targets. A fit's folder thus holds
/// either the last run's files or the new run's, never some of each. Only
/// a rename that fails after others succeeded (the disk pulled away
/// between two renames) can leave a mix. An error names the file.
pub fn write_all_atomic(files: &[(&Path, &[u8])]) -> io::Result<()> {
    let named =
        |path: &Path, e: io::Error| io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    let mut staged: Vec<(PathBuf, &Path)> = Vec::with_capacity(files.len());
    let result = (|| {
        for &(path, bytes) in files {
            let tmp = stage(path, bytes).map_err(|e| named(path, e))?;
            staged.push((tmp, path));
        }
        if let Some(folder) = files.iter().map(|f| f.0).find(|p| p.is_dir()) {
            return Err(io::Error::other(format!(
                "{} is a folder, not a file",
                folder.display()
            )));
        }
        while let Some((tmp, path)) = staged.first() {
            fs::rename(tmp, path).map_err(|e| named(path, e))?;
            staged.remove(0);
        }
        Ok(())
    })();
    for (tmp, _) in &staged {
        let _ = fs::remove_file(tmp);
    }
    result
}

/// Writes `bytes` to a temporary file beside `path` (creating the folder)
/// and returns its name.
fn stage(path: &Path, bytes: &[u8]) -> io::Result<PathBuf> {
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
    let written = (|| {
        let mut f = fs::File::create(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()
    })();
    match written {
        Ok(()) => Ok(tmp),
        Err(e) => {
            let _ = fs::remove_file(&tmp);
            Err(e)
        }
    }
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
    fn a_set_is_written_whole_or_not_at_all() {
        let dir = tempfile::tempdir().unwrap();
        let (a, b) = (dir.path().join("a.json"), dir.path().join("b.svg"));
        write_all_atomic(&[(&a, b"one"), (&b, b"one")]).unwrap();
        // A folder where the second file goes: neither is replaced, and no
        // temporary is left.
        fs::remove_file(&b).unwrap();
        fs::create_dir(&b).unwrap();
        let err = write_all_atomic(&[(&a, b"two"), (&b, b"two")])
            .unwrap_err()
            .to_string();
        assert!(err.contains("b.svg is a folder"), "{err}");
        assert_eq!(fs::read(&a).unwrap(), b"one");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2);
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
