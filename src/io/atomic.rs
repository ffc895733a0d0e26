//! Write-then-rename, so that a failure never leaves a half-written output behind; what a
//! killed run leaves (its temporary files) removed by the next write of the same file; one
//! writer at a time per output folder.

use crate::error::{Error, Result};
use std::fs;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

/// Write a file through `write`, into a temporary file beside `path` that is renamed over
/// `path` only when `write` succeeded and the data is flushed. On any error the temporary file
/// is removed and `path` is left as it was.
pub fn write_atomic<F>(path: &Path, write: F) -> Result<()>
where
    F: FnOnce(&mut dyn Write) -> std::io::Result<()>,
{
    for stale in stale_temporaries_of(path) {
        if fs::remove_file(&stale).is_ok() {
            log::info!(
                "removed {}, a temporary file a killed run left",
                stale.display()
            );
        }
    }
    let tmp = temp_path(path);
    let result = (|| -> std::io::Result<()> {
        let file = fs::File::create(&tmp)?;
        let mut w = BufWriter::new(file);
        write(&mut w)?;
        let file = w.into_inner().map_err(|e| e.into_error())?;
        file.sync_all()?;
        fs::rename(&tmp, path)
    })();
    if let Err(e) = result {
        let _ = fs::remove_file(&tmp);
        return Err(Error::io(path, e));
    }
    Ok(())
}

/// [`write_atomic`] for bytes already in memory.
pub fn write_bytes_atomic(path: &Path, bytes: &[u8]) -> Result<()> {
    write_atomic(path, |w| w.write_all(bytes))
}

/// A temporary file older than this is stale whoever wrote it: no single write of the toolkit
/// takes as long, so it was left by a killed run (on this machine or another sharing the
/// folder).
pub const STALE_TEMPORARY_AFTER: std::time::Duration = std::time::Duration::from_secs(600);

/// This boot of this machine, as temporary names carry it: the first eight characters of
/// Linux's boot id, or `x` where there is none (then only [`STALE_TEMPORARY_AFTER`] tells a
/// stale file).
fn boot_tag() -> &'static str {
    static TAG: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    TAG.get_or_init(|| {
        fs::read_to_string("/proc/sys/kernel/random/boot_id")
            .ok()
            .map(|id| id.trim().chars().filter(|c| *c != '-').take(8).collect())
            .filter(|t: &String| t.len() == 8)
            .unwrap_or_else(|| "x".into())
    })
}

/// Whether the temporary file `name` (of [`temp_path`]'s form, `.NAME.BOOT.PID.N.NANOS.tmp`)
/// is stale: written during this boot of this machine by a process that no longer runs, or
/// older than [`STALE_TEMPORARY_AFTER`] (`age`; `None`: unknown). A file of another form is
/// never stale.
pub fn is_stale_temporary(name: &str, age: Option<std::time::Duration>) -> bool {
    if !(name.starts_with('.') && name.ends_with(".tmp")) {
        return false;
    }
    if age.is_some_and(|a| a >= STALE_TEMPORARY_AFTER) {
        return true;
    }
    let parts: Vec<&str> = name.rsplitn(6, '.').collect();
    // tmp, nanos, counter, pid, boot, rest
    if parts.len() < 6 || parts[4] != boot_tag() || boot_tag() == "x" {
        return false;
    }
    match parts[3].parse::<u32>() {
        Ok(pid) if pid != std::process::id() => !Path::new(&format!("/proc/{pid}")).exists(),
        _ => false,
    }
}

/// The stale temporary files of `path` ([`is_stale_temporary`]) in its folder.
fn stale_temporaries_of(path: &Path) -> Vec<PathBuf> {
    let (Some(dir), Some(name)) = (path.parent(), path.file_name()) else {
        return Vec::new();
    };
    let dir = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    stale_named(dir, &format!(".{}.", name.to_string_lossy()))
}

/// Every stale temporary file ([`is_stale_temporary`]) directly in `dir`, sorted.
pub fn stale_temporaries_in(dir: &Path) -> Vec<PathBuf> {
    stale_named(dir, ".")
}

/// The stale temporary files directly in `dir` whose names start with `prefix`, sorted (the
/// name is matched before the file's times are read: a write into a full folder reads only its
/// own file's temporaries).
fn stale_named(dir: &Path, prefix: &str) -> Vec<PathBuf> {
    let now = std::time::SystemTime::now();
    let mut out: Vec<PathBuf> = fs::read_dir(dir)
        .into_iter()
        .flatten()
        .flatten()
        .filter(|e| {
            if !e.file_name().to_string_lossy().starts_with(prefix) {
                return false;
            }
            let Ok(meta) = e.metadata() else {
                return false;
            };
            let age = meta
                .modified()
                .ok()
                .and_then(|m| now.duration_since(m).ok());
            meta.is_file() && is_stale_temporary(&e.file_name().to_string_lossy(), age)
        })
        .map(|e| e.path())
        .collect();
    out.sort();
    out
}

/// An output folder held by one writer: while it lives, another process asking for the same
/// folder waits ([`FolderLock::acquire`]), so that two runs into one folder give the files of
/// one run, never a mix. Released when dropped or when the process dies (an advisory lock of
/// the operating system on the folder itself: nothing is left in it).
pub struct FolderLock {
    _dir: Option<fs::File>,
}

impl FolderLock {
    /// Create `dir` if needed and hold it, waiting (with a note) while another run holds it.
    /// Where folders cannot be locked (an operating system that cannot open a folder as a
    /// file, or a file system without locks) it holds nothing and says so at debug level.
    pub fn acquire(dir: &Path) -> Result<FolderLock> {
        fs::create_dir_all(dir).map_err(|e| Error::io(dir, e))?;
        let held = fs::File::open(dir).and_then(|file| {
            match file.try_lock() {
                Ok(()) => {}
                Err(fs::TryLockError::WouldBlock) => {
                    log::info!(
                        "{}: another ergohand run is writing there; waiting for it to finish",
                        dir.display()
                    );
                    file.lock()?;
                }
                Err(fs::TryLockError::Error(e)) => return Err(e),
            }
            Ok(file)
        });
        if let Err(e) = &held {
            log::debug!("{}: the folder cannot be locked here: {e}", dir.display());
        }
        Ok(FolderLock { _dir: held.ok() })
    }
}

/// The temporary sibling of `path`: same folder (so the rename stays on one file system),
/// hidden, and unique per write: this boot of this machine and the process id (so that a later
/// run can tell a dead writer's file, [`is_stale_temporary`]), a per-process counter (threads
/// of one `ergohand batch` writing the same file, e.g. the tet cache) and the clock's
/// nanoseconds (processes with the same id on different cluster nodes sharing a cache folder).
fn temp_path(path: &Path) -> PathBuf {
    use std::sync::atomic::{AtomicU64, Ordering};
    static WRITES: AtomicU64 = AtomicU64::new(0);
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "out".into());
    let nanos = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| d.subsec_nanos());
    path.with_file_name(format!(
        ".{name}.{}.{}.{}.{nanos}.tmp",
        boot_tag(),
        std::process::id(),
        WRITES.fetch_add(1, Ordering::Relaxed)
    ))
}

/// Read a whole file, naming it in the error.
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    fs::read(path).map_err(|e| Error::io(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn failure_leaves_nothing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.txt");
        fs::write(&p, b"old").unwrap();
        let r = write_atomic(&p, |w| {
            w.write_all(b"half")?;
            Err(std::io::Error::other("boom"))
        });
        assert!(r.is_err());
        assert_eq!(fs::read(&p).unwrap(), b"old");
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 1);
        write_bytes_atomic(&p, b"new").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"new");
    }

    /// The id of a process that has ended: a child waited for.
    fn dead_pid() -> u32 {
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let pid = child.id();
        child.wait().unwrap();
        pid
    }

    #[test]
    fn a_dead_writers_temporary_is_removed_by_the_next_write_and_a_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("tet.vtk");
        let tag = boot_tag();
        let dead = dir
            .path()
            .join(format!(".tet.vtk.{tag}.{}.0.1.tmp", dead_pid()));
        // A live writer: this process's parent (the test harness's launcher is alive).
        let live = dir.path().join(format!(
            ".tet.vtk.{tag}.{}.0.2.tmp",
            std::os::unix::process::parent_id()
        ));
        let other_boot = dir
            .path()
            .join(format!(".tet.vtk.zzzzzzzz.{}.0.3.tmp", dead_pid()));
        let other_file = dir
            .path()
            .join(format!(".skin.obj.{tag}.{}.0.4.tmp", dead_pid()));
        let not_ours = dir.path().join(".notes.tmp");
        for f in [&dead, &live, &other_boot, &other_file, &not_ours] {
            fs::write(f, b"half").unwrap();
        }
        write_bytes_atomic(&p, b"whole").unwrap();
        assert_eq!(fs::read(&p).unwrap(), b"whole");
        if tag == "x" {
            return; // no boot id here: only the age rule applies
        }
        assert!(
            !dead.exists(),
            "a dead writer's temporary of the same file goes"
        );
        for kept in [&live, &other_boot, &other_file, &not_ours] {
            assert!(kept.exists(), "{} kept", kept.display());
        }
        assert_eq!(stale_temporaries_in(dir.path()), vec![other_file.clone()]);
        // Ten minutes old: stale whoever wrote it.
        assert!(is_stale_temporary(
            ".tet.vtk.zzzzzzzz.1.0.3.tmp",
            Some(STALE_TEMPORARY_AFTER)
        ));
        assert!(!is_stale_temporary(".tet.vtk", Some(STALE_TEMPORARY_AFTER)));
    }

    #[test]
    fn a_held_folder_waits_for_its_writer() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        let first = FolderLock::acquire(&out).unwrap();
        assert!(
            first._dir.is_some(),
            "a folder on this file system can be locked"
        );
        let (tx, rx) = std::sync::mpsc::channel();
        let o = out.clone();
        let waiter = std::thread::spawn(move || {
            let _second = FolderLock::acquire(&o).unwrap();
            tx.send(()).unwrap();
        });
        // Still waiting while the first holds it (a lock on a separately opened file
        // description excludes threads of one process as it does processes).
        assert!(rx
            .recv_timeout(std::time::Duration::from_millis(300))
            .is_err());
        drop(first);
        rx.recv_timeout(std::time::Duration::from_secs(10))
            .expect("acquired once released");
        waiter.join().unwrap();
        assert_eq!(fs::read_dir(&out).unwrap().count(), 0, "nothing left in it");
    }
}
