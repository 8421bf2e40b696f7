//! Writes that never leave a half-written file behind: the bytes go to a
//! temporary file beside the target, which is then renamed over it.

use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

/// Creates the folder `dir` and its parents, as `fs::create_dir_all`; where
/// a part of the path is a file, the error names it (the OS says "File
/// exists" or "Not a directory").
pub fn create_dir_all(dir: &Path) -> io::Result<()> {
    // Without a trailing separator, which would make a file's name read
    // as no file at all.
    let plain: PathBuf = dir.components().collect();
    fs::create_dir_all(dir).map_err(|e| match plain.ancestors().find(|a| a.is_file()) {
        Some(file) if file == plain => {
            io::Error::other(format!("{} is a file, not a folder", plain.display()))
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
    let path = &target(path)?;
    let tmp = stage(path, bytes)?;
    fs::rename(&tmp, path).inspect_err(|_| {
        let _ = fs::remove_file(&tmp);
    })
}

/// The file a write to `path` replaces: through a symbolic link, the file
/// it points to (a rename would replace the link itself). A folder, a name
/// ending in a separator (a folder to be), and something that is not a
/// regular file (a device such as `/dev/null`, a pipe) cannot be replaced
/// by a file, and are errors that name the path.
fn target(path: &Path) -> io::Result<PathBuf> {
    let text = path.as_os_str().as_encoded_bytes();
    if text
        .last()
        .is_some_and(|&c| std::path::is_separator(c as char))
    {
        return Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            format!(
                "{} ends in a separator, so it names a folder: give a file name in it",
                path.display()
            ),
        ));
    }
    let resolved = match fs::symlink_metadata(path) {
        Ok(m) if m.file_type().is_symlink() => match fs::canonicalize(path) {
            Ok(p) => p,
            // A link to nothing yet: the file it names is written.
            Err(_) => {
                let to = fs::read_link(path)?;
                path.parent().map_or(to.clone(), |d| d.join(to))
            }
        },
        _ => path.to_path_buf(),
    };
    match fs::metadata(&resolved) {
        Ok(m) if m.is_dir() => Err(io::Error::new(
            io::ErrorKind::IsADirectory,
            format!("{} is a folder, not a file", path.display()),
        )),
        Ok(m) if !m.is_file() => Err(io::Error::other(format!(
            "{} is not a regular file (a device or a pipe): give a file to write",
            path.display()
        ))),
        _ => Ok(resolved),
    }
}

/// Writes every file of `files` or none: each goes first to a temporary
/// file beside its target, and only once all are written (and no target is
/// a folder) are they renamed over their targets. A target that exists is
/// first linked to a backup, so that a rename failing after others
/// succeeded (a file made immutable, the disk pulled away) puts the ones
/// already replaced back. A fit's folder thus holds
/// either the last run's files or the new run's, never some of each; only
/// a crash between two renames can leave a mix (and the backups, hidden
/// beside their files). An error names the file.
pub fn write_all_atomic(files: &[(&Path, &[u8])]) -> io::Result<()> {
    write_all_atomic_with(files, |from, to| fs::rename(from, to))
}

/// [`write_all_atomic`], its renames made by `rename` (a test makes one
/// fail).
fn write_all_atomic_with(
    files: &[(&Path, &[u8])],
    rename: impl Fn(&Path, &Path) -> io::Result<()>,
) -> io::Result<()> {
    let named =
        |path: &Path, e: io::Error| io::Error::new(e.kind(), format!("{}: {e}", path.display()));
    // Every target is checked (a folder in the way, a device) before any
    // file is staged.
    let targets: Vec<PathBuf> = files
        .iter()
        .map(|&(path, _)| target(path))
        .collect::<io::Result<_>>()?;
    let mut staged: Vec<PathBuf> = Vec::with_capacity(files.len());
    // Each target's backup, where it existed.
    let mut backups: Vec<Option<PathBuf>> = Vec::with_capacity(files.len());
    let mut renamed = 0;
    let result = (|| {
        for (&(_, bytes), path) in files.iter().zip(&targets) {
            staged.push(stage(path, bytes).map_err(|e| named(path, e))?);
        }
        for path in &targets {
            backups.push(backup(path).map_err(|e| named(path, e))?);
        }
        for (tmp, path) in staged.iter().zip(&targets) {
            rename(tmp, path).map_err(|e| named(path, e))?;
            renamed += 1;
        }
        Ok(())
    })();
    if result.is_err() {
        // Put back what was replaced: the old file where there was one,
        // nothing where there was none.
        for (path, kept) in targets.iter().zip(&backups).take(renamed) {
            let _ = match kept {
                Some(kept) => fs::rename(kept, path),
                None => fs::remove_file(path),
            };
        }
        for tmp in &staged[renamed..] {
            let _ = fs::remove_file(tmp);
        }
    }
    for kept in backups.iter().flatten() {
        let _ = fs::remove_file(kept);
    }
    result
}

/// A hard link to the file at `path` beside it, where one exists (a copy
/// where the file system takes no links, as FAT): the old file stays
/// reachable after a rename replaces `path`. `None` where there is no file
/// yet.
fn backup(path: &Path) -> io::Result<Option<PathBuf>> {
    if !path.exists() {
        return Ok(None);
    }
    let name = path
        .file_name()
        .ok_or_else(|| io::Error::other(format!("{} names no file", path.display())))?;
    let kept = path.with_file_name(format!(
        ".{}.old-{}",
        name.to_string_lossy(),
        std::process::id()
    ));
    let _ = fs::remove_file(&kept);
    if fs::hard_link(path, &kept).is_err() {
        fs::copy(path, &kept)?;
    }
    Ok(Some(kept))
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
    // The process and a count of its writes: two threads writing one
    // target (Python's `Model.save` releases the interpreter) each stage
    // their own file, and the last rename wins whole.
    static WRITES: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let write = WRITES.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let tmp = dir.join(format!(
        ".{}.tmp-{}-{write}",
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

    /// Threads writing one file each stage their own temporary: every
    /// write succeeds and the file is always one of them whole (they
    /// shared one name, and a rename found it gone or half-written).
    #[test]
    fn threads_writing_one_file_never_meet() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("model.json");
        let texts = ["a".repeat(100_000), "b".repeat(50_000)];
        std::thread::scope(|s| {
            for text in &texts {
                let path = &path;
                s.spawn(move || {
                    for _ in 0..100 {
                        write_atomic(path, text.as_bytes()).unwrap();
                    }
                });
            }
            for _ in 0..100 {
                if let Ok(read) = fs::read_to_string(&path) {
                    assert!(texts.contains(&read), "{} bytes, mixed", read.len());
                }
            }
        });
        let left: Vec<_> = fs::read_dir(dir.path()).unwrap().collect();
        assert_eq!(left.len(), 1, "temporaries left behind");
    }

    #[test]
    fn a_folder_through_a_file_names_the_file() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("notadir");
        fs::write(&file, "").unwrap();
        let err = write_atomic(&file.join("x.csv"), b"t\n")
            .unwrap_err()
            .to_string();
        assert!(err.contains("notadir is a file"), "{err}");
        // A file named as a folder (`--out model.json/`).
        let err = create_dir_all(&dir.path().join("notadir/"))
            .unwrap_err()
            .to_string();
        assert!(err.contains("notadir is a file, not a folder"), "{err}");
    }

    /// A folder, or a name that ends as a folder's, is named as such, and
    /// nothing is left beside it (a temporary was staged in the parent
    /// before the rename failed with "Is a directory").
    #[test]
    fn a_folder_is_named_and_nothing_is_staged() {
        let dir = tempfile::tempdir().unwrap();
        let folder = dir.path().join("out");
        fs::create_dir(&folder).unwrap();
        let err = write_atomic(&folder, b"x").unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::IsADirectory);
        assert!(
            err.to_string().contains("out is a folder, not a file"),
            "{err}"
        );
        let to_be = dir.path().join("new/");
        let err = write_atomic(&to_be, b"x").unwrap_err();
        assert_eq!(err.kind(), io::ErrorKind::IsADirectory);
        assert!(err.to_string().contains("ends in a separator"), "{err}");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
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

    /// A rename that fails after others succeeded puts back the files
    /// already replaced (and removes one that was new), leaving no
    /// temporary and no backup.
    #[test]
    fn a_rename_failing_midway_puts_the_replaced_files_back() {
        let dir = tempfile::tempdir().unwrap();
        let [a, b, c] = ["a.json", "b.csv", "c.svg"].map(|n| dir.path().join(n));
        write_all_atomic(&[(&a, b"one"), (&b, b"one")]).unwrap();
        let calls = std::cell::Cell::new(0);
        let third_fails = |from: &Path, to: &Path| {
            calls.set(calls.get() + 1);
            match calls.get() {
                3 => Err(io::Error::other("the disk went away")),
                _ => fs::rename(from, to),
            }
        };
        let err = write_all_atomic_with(&[(&a, b"two"), (&c, b"two"), (&b, b"two")], third_fails)
            .unwrap_err()
            .to_string();
        assert!(err.contains("b.csv: the disk went away"), "{err}");
        assert_eq!(fs::read(&a).unwrap(), b"one");
        assert_eq!(fs::read(&b).unwrap(), b"one");
        assert!(!c.exists(), "a file that was new is removed again");
        assert_eq!(
            fs::read_dir(dir.path()).unwrap().count(),
            2,
            "a temporary or backup left"
        );
        // And a set that succeeds leaves no backup either.
        write_all_atomic(&[(&a, b"three"), (&b, b"three")]).unwrap();
        assert_eq!(fs::read(&a).unwrap(), b"three");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 2);
    }

    #[cfg(unix)]
    #[test]
    fn a_link_is_written_through_and_a_device_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("real.json");
        let link = dir.path().join("link.json");
        fs::write(&file, "old").unwrap();
        std::os::unix::fs::symlink(&file, &link).unwrap();
        write_atomic(&link, b"new").unwrap();
        assert!(
            fs::symlink_metadata(&link)
                .unwrap()
                .file_type()
                .is_symlink()
        );
        assert_eq!(fs::read(&file).unwrap(), b"new");
        let err = write_atomic(Path::new("/dev/null"), b"x")
            .unwrap_err()
            .to_string();
        assert!(err.contains("/dev/null is not a regular file"), "{err}");
        assert!(!fs::metadata("/dev/null").unwrap().is_file());
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
