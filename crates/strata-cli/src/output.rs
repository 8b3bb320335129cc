//! Output files, and what a failed or interrupted run leaves behind: nothing.
//!
//! Every output is written to a temporary file beside its target, then
//! renamed (`stage` + `commit`, or `write_atomic` for one file), so no reader
//! ever sees a half-written file. The temporary files and the directories a
//! run creates are registered here: when the run fails (`clean_up`, called by
//! `main`) or is interrupted (SIGINT, SIGTERM, SIGHUP: `on_interrupt_clean_up`)
//! the temporary files are removed, and so are the directories it created if
//! they are still empty. An interrupted run exits with status 130.

use std::fs;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::{Mutex, MutexGuard, PoisonError};

/// What this run would leave behind if it stopped now.
struct Debris {
    /// Temporary files not yet renamed to their targets.
    temps: Vec<PathBuf>,
    /// Directories this run created, outermost first.
    dirs: Vec<PathBuf>,
}

static DEBRIS: Mutex<Debris> = Mutex::new(Debris {
    temps: Vec::new(),
    dirs: Vec::new(),
});

/// The registry, locked. Whoever holds it can create or rename a temporary
/// file without an interrupt's clean-up running in between.
fn debris() -> MutexGuard<'static, Debris> {
    DEBRIS.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Debris {
    fn clean(&mut self) {
        for t in self.temps.drain(..) {
            let _ = fs::remove_file(&t);
        }
        // Innermost first; `remove_dir` leaves a directory that holds anything.
        for d in self.dirs.drain(..).rev() {
            let _ = fs::remove_dir(&d);
        }
    }
}

/// Installs the handler of SIGINT, SIGTERM and SIGHUP: it removes the
/// temporary files and the still-empty directories of this run and exits
/// with status 130. It keeps the registry locked until the process is gone,
/// so the run cannot create another temporary file meanwhile.
pub fn on_interrupt_clean_up() -> Result<(), String> {
    ctrlc::set_handler(|| {
        let mut d = debris();
        d.clean();
        let _ = writeln!(std::io::stderr(), "strata: interrupted");
        std::process::exit(130);
    })
    .map_err(|e| format!("cannot install the interrupt handler: {e}"))
}

/// Removes the temporary files of this run and the directories it created
/// that are still empty. `main` calls it when a command ends.
pub fn clean_up() {
    debris().clean();
}

/// Creates `dir` and its missing parents, registering each one it creates.
fn ensure_dir(dir: &Path) -> std::io::Result<()> {
    let mut missing = Vec::new();
    let mut d = Some(dir);
    while let Some(p) = d.filter(|p| !p.as_os_str().is_empty() && !p.exists()) {
        missing.push(p.to_path_buf());
        d = p.parent();
    }
    if missing.is_empty() {
        return if dir.as_os_str().is_empty() || dir.is_dir() {
            Ok(())
        } else {
            Err(std::io::Error::other("it exists and is not a directory"))
        };
    }
    missing.reverse();
    // Registered and created under one lock, so that an interrupt's clean-up
    // cannot run between the two and leave a directory it did not know of.
    let mut d = debris();
    d.dirs.extend(missing);
    fs::create_dir_all(dir)
}

/// Makes sure files can be written into the output directory `dir` (given by
/// `flag`) before any work is done: creates it if missing and creates and
/// removes a probe file in it.
pub fn prepare_dir(flag: &str, dir: &Path) -> Result<(), String> {
    let fail = |what: &str, e: std::io::Error| format!("{flag} {}: {what}: {e}", dir.display());
    ensure_dir(dir).map_err(|e| fail("cannot create the directory", e))?;
    let probe = dir.join(format!(".strata-probe{}", std::process::id()));
    create_temp(&probe).map_err(|e| fail("cannot write into the directory", e))?;
    discard(&probe);
    Ok(())
}

/// Fails, naming it, if `path` is there and is not a file (a directory, say),
/// so that a run finds out before its work that it could not write it.
pub fn check_target(path: &Path) -> Result<(), String> {
    match fs::metadata(path) {
        Ok(m) if !m.is_file() => Err(format!(
            "cannot write {}: a directory (or other non-file) is in the way",
            path.display()
        )),
        _ => Ok(()),
    }
}

/// Creates the temporary file `tmp`, registered for removal.
fn create_temp(tmp: &Path) -> std::io::Result<fs::File> {
    let mut d = debris();
    let f = fs::File::create(tmp)?;
    d.temps.push(tmp.to_path_buf());
    Ok(f)
}

/// Removes the temporary file `tmp` and forgets it.
fn discard(tmp: &Path) {
    let mut d = debris();
    let _ = fs::remove_file(tmp);
    d.temps.retain(|t| t != tmp);
}

/// An output written to a temporary file beside its target, not yet renamed.
pub struct Staged {
    tmp: PathBuf,
    path: PathBuf,
}

/// Writes `bytes` to a temporary file beside `path` (creating its directory
/// if needed); `commit` puts it in place.
pub fn stage(path: &Path, bytes: &[u8]) -> Result<Staged, String> {
    let fail = |e: std::io::Error| format!("cannot write {}: {e}", path.display());
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        ensure_dir(dir).map_err(|e| format!("cannot create {}: {e}", dir.display()))?;
    }
    check_target(path)?;
    let name = path
        .file_name()
        .ok_or_else(|| format!("not a file path: {}", path.display()))?
        .to_string_lossy()
        .into_owned();
    let tmp = path.with_file_name(format!(".{name}.tmp{}", std::process::id()));
    let mut f = create_temp(&tmp).map_err(fail)?;
    if let Err(e) = f.write_all(bytes).and_then(|()| f.sync_all()) {
        drop(f);
        discard(&tmp);
        return Err(fail(e));
    }
    Ok(Staged {
        tmp,
        path: path.to_path_buf(),
    })
}

/// Renames the staged files to their targets, all or none. The files the
/// targets replace are first moved aside; if a rename fails, the new targets
/// are removed, the old files put back and the temporaries removed, so a
/// failed run leaves the outputs as they were before it. An interrupt waits
/// until the set is in place (or put back).
pub fn commit(files: Vec<Staged>) -> Result<(), String> {
    let mut d = debris();
    let fail = |p: &Path, e: std::io::Error| format!("cannot write {}: {e}", p.display());
    let mut result = Ok(());
    // (old file moved aside, its target)
    let mut aside: Vec<(PathBuf, &Path)> = Vec::new();
    for s in &files {
        if s.path.is_file() {
            let old = s.tmp.with_extension("old");
            if let Err(e) = fs::rename(&s.path, &old) {
                result = Err(fail(&s.path, e));
                break;
            }
            aside.push((old, &s.path));
        }
    }
    let mut done: Vec<&Path> = Vec::new();
    if result.is_ok() {
        for s in &files {
            if let Err(e) = fs::rename(&s.tmp, &s.path) {
                result = Err(fail(&s.path, e));
                break;
            }
            done.push(&s.path);
        }
    }
    if result.is_err() {
        for p in done {
            let _ = fs::remove_file(p);
        }
        for (old, target) in &aside {
            let _ = fs::rename(old, target);
        }
        for s in &files {
            let _ = fs::remove_file(&s.tmp);
        }
    } else {
        for (old, _) in &aside {
            let _ = fs::remove_file(old);
        }
    }
    d.temps.retain(|t| !files.iter().any(|s| &s.tmp == t));
    result
}

/// Writes `bytes` to `path` atomically (temporary file + rename).
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), String> {
    commit(vec![stage(path, bytes)?])
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A set whose second rename fails leaves every target as it was: the
    /// first target's earlier content is back, no temporary or moved-aside
    /// file is left, and the error names the target that failed.
    #[test]
    fn a_failed_commit_puts_the_old_outputs_back() {
        let dir = std::env::temp_dir().join(format!("strata-commit-{}", std::process::id()));
        let _ = fs::remove_dir_all(&dir);
        fs::create_dir_all(&dir).unwrap();
        let (a, b) = (dir.join("a.csv"), dir.join("b.md"));
        fs::write(&a, "old a").unwrap();
        let staged = vec![stage(&a, b"new a").unwrap(), stage(&b, b"new b").unwrap()];
        // Something appears in b's way after the checks: a non-empty directory.
        fs::create_dir_all(b.join("x")).unwrap();
        let e = commit(staged).expect_err("b cannot be replaced");
        assert!(e.contains("b.md"), "{e}");
        assert_eq!(fs::read_to_string(&a).unwrap(), "old a");
        let mut left: Vec<String> = fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        left.sort();
        assert_eq!(left, ["a.csv", "b.md"]);
        // And a set that can be written replaces the old file, leaving nothing else.
        fs::remove_dir_all(&b).unwrap();
        commit(vec![
            stage(&a, b"new a").unwrap(),
            stage(&b, b"new b").unwrap(),
        ])
        .unwrap();
        assert_eq!(fs::read_to_string(&a).unwrap(), "new a");
        assert_eq!(fs::read_to_string(&b).unwrap(), "new b");
        assert_eq!(fs::read_dir(&dir).unwrap().count(), 2);
        fs::remove_dir_all(&dir).unwrap();
    }
}
