//! Output files appear complete or not at all.

use std::io::Write;
use std::path::{Path, PathBuf};

/// The temporary sibling a file is written to before it takes its name.
pub fn partial_path(path: &Path) -> PathBuf {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".partial");
    PathBuf::from(tmp)
}

/// Write `path` through `path.partial`: filled by `fill`, synced, then renamed. On any
/// error the partial file is removed, so a reader never sees a half-written file. A missing
/// parent directory is made (found by trying: the walk-through's `hil-sim identify --out
/// out/walk/motor.toml` in a fresh clone ran its 14.5 s of identification, then could not
/// write the motor file).
pub fn write_atomic(
    path: &Path,
    fill: impl FnOnce(&mut dyn Write) -> std::io::Result<()>,
) -> Result<(), String> {
    let tmp = partial_path(path);
    let parent = path.parent().filter(|p| !p.as_os_str().is_empty());
    let written = parent
        .map_or(Ok(()), std::fs::create_dir_all)
        .and_then(|()| std::fs::File::create(&tmp))
        .and_then(|f| {
            let mut w = std::io::BufWriter::new(f);
            fill(&mut w)?;
            w.into_inner().map_err(|e| e.into_error())?.sync_all()?;
            std::fs::rename(&tmp, path)
        });
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written.map_err(|e| format!("cannot write {}: {e}", path.display()))
}

/// [`write_atomic`] of a string.
pub fn write_text(path: &Path, text: &str) -> Result<(), String> {
    write_atomic(path, |w| w.write_all(text.as_bytes()))
}

/// `dir` can be an output directory: it does not exist yet, or it is one. Checked before a
/// command writes anything, so that a directory argument naming a file fails first — not
/// after the command's other files were written, with "File exists (os error 17)" (found by
/// trying: `design certify --out c.json --plot-dir <a file>` wrote the certificate, then
/// exited 2).
pub fn check_dir(dir: &Path) -> Result<(), String> {
    if dir.exists() && !dir.is_dir() {
        return Err(format!("{} exists and is not a directory", dir.display()));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_missing_directory_is_made() {
        let dir = std::env::temp_dir().join(format!("drive-file-write-dir-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let p = dir.join("a").join("b.txt");
        write_text(&p, "x").unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "x");
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn failed_fill_leaves_nothing() {
        let dir = std::env::temp_dir().join(format!("drive-file-write-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("x.txt");
        let e = write_atomic(&p, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("stop"))
        });
        assert!(e.is_err() && !p.exists() && !partial_path(&p).exists());
        write_text(&p, "whole").unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), "whole");
        // A parent that is a file cannot be made a directory: the error names the path.
        assert!(write_text(&p.join("x"), "x").unwrap_err().contains("x.txt"));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
