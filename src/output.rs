//! Writing result files so that a failure or a kill never leaves a half-written file: write to
//! a temporary file in the same folder, flush, then rename over the target. Only regular files
//! (and new paths) are written that way: a device, a FIFO or a dangling symlink is written
//! through (a rename would replace the device node with a file and hide a full disk), and a
//! symlink to a regular file has its target replaced, so the link stays.

use std::cell::RefCell;
use std::io::Write;
use std::path::{Path, PathBuf};

use crate::error::{Error, Result};

/// The renames an `all_or_none` scope holds back, (temporary, target), in write order; None
/// once the scope has ended (a late commit then renames at once). Shared: a `PendingFile`
/// created in the scope may be committed from another thread (a writer thread).
type HeldBack = std::sync::Arc<std::sync::Mutex<Option<Vec<(PathBuf, PathBuf)>>>>;

thread_local! {
    /// The innermost `all_or_none` scope this thread is in.
    static HELD_BACK: RefCell<Option<HeldBack>> = const { RefCell::new(None) };
}

/// Ends a scope however `write` leaves it (a panic that unwinds included): restores the outer
/// scope and removes the temporaries of renames still held back.
struct ScopeGuard {
    scope: HeldBack,
    outer: Option<HeldBack>,
}

impl ScopeGuard {
    /// The renames held back, and the scope closed to later commits.
    fn close(&self) -> Vec<(PathBuf, PathBuf)> {
        self.scope
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .take()
            .unwrap_or_default()
    }
}

impl Drop for ScopeGuard {
    fn drop(&mut self) {
        HELD_BACK.with(|h| *h.borrow_mut() = self.outer.take());
        for (tmp, _) in self.close() {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// Runs `write`, which writes a command's outputs, so that they appear together or not at all:
/// the files written atomically (regular files, `write_atomically`, `PendingFile`) are renamed
/// into place only when `write` has succeeded; when it fails none is, and their temporaries are
/// removed (a run whose JSON cannot be written leaves no PNG that looks like a result). A target
/// that is a folder fails them all before any is renamed. The renames then follow one another:
/// should one of them fail (the folder removed meanwhile), those before it are done. Outputs
/// written through (devices, FIFOs) are written as they come.
/// `write` should print nothing: a failed print ends the process without unwinding (`main`'s
/// panic hook), which would leave the temporaries for the next write to the same path to remove.
pub fn all_or_none<T, E: From<Error>>(
    write: impl FnOnce() -> std::result::Result<T, E>,
) -> std::result::Result<T, E> {
    let scope = HeldBack::new(std::sync::Mutex::new(Some(Vec::new())));
    let outer = HELD_BACK.with(|h| h.borrow_mut().replace(scope.clone()));
    let guard = ScopeGuard { scope, outer };
    // On an error the guard removes the temporaries.
    let value = write()?;
    let held = guard.close();
    // A target that is a folder would refuse its rename after the others were done: checked
    // first, so that case too leaves nothing.
    if let Some((_, path)) = held.iter().find(|(_, path)| path.is_dir()) {
        for (tmp, _) in &held {
            let _ = std::fs::remove_file(tmp);
        }
        return Err(Error::Invalid(format!("{}: is a folder, not a file", path.display())).into());
    }
    for (i, (tmp, path)) in held.iter().enumerate() {
        if let Err(e) = std::fs::rename(tmp, path) {
            for (tmp, _) in &held[i..] {
                let _ = std::fs::remove_file(tmp);
            }
            return Err(Error::io(path, e).into());
        }
    }
    Ok(value)
}

/// The `all_or_none` scope this thread is in, if any.
fn current_scope() -> Option<HeldBack> {
    HELD_BACK.with(|h| h.borrow().clone())
}

/// Renames a finished temporary to its target, or holds the rename back while `scope` lasts.
fn move_into_place(scope: Option<&HeldBack>, tmp: &Path, path: &Path) -> std::io::Result<()> {
    if let Some(scope) = scope {
        if let Some(held) = scope.lock().unwrap_or_else(|e| e.into_inner()).as_mut() {
            held.push((tmp.to_path_buf(), path.to_path_buf()));
            return Ok(());
        }
    }
    std::fs::rename(tmp, path)
}

/// Moves a finished temporary that a library wrote by path itself (plotters' charts) to `path`,
/// or, inside an `all_or_none` scope, holds the move back with the scope's other outputs. When
/// the move fails the temporary is removed: nothing is left under either name.
pub fn place_finished(tmp: &Path, path: &Path) -> Result<()> {
    move_into_place(current_scope().as_ref(), tmp, path).map_err(|e| {
        let _ = std::fs::remove_file(tmp);
        Error::io(path, e)
    })
}

/// The temporary name a file is written under before it is renamed to `path`: hidden, in the
/// same folder (created if missing), so the rename never crosses file systems.
fn temporary_path(path: &Path) -> Result<std::path::PathBuf> {
    temporary_path_ending(path, "")
}

/// `temporary_path` ending in `path`'s own extension (`.chart.png.tmp123.png`), for writers
/// that choose the format by the extension (plotters' bitmap backend); cleaned up alike.
pub fn temporary_path_keeping_extension(path: &Path) -> Result<std::path::PathBuf> {
    let ending = match path.extension() {
        Some(ext) => format!(".{}", ext.to_string_lossy()),
        None => String::new(),
    };
    temporary_path_ending(path, &ending)
}

fn temporary_path_ending(path: &Path, ending: &str) -> Result<std::path::PathBuf> {
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
        _ => std::path::PathBuf::from("."),
    };
    std::fs::create_dir_all(&dir).map_err(|e| Error::io(&dir, e))?;
    let file_name = path
        .file_name()
        .ok_or_else(|| Error::Invalid(format!("{}: not a file path", path.display())))?;
    let prefix = format!(".{}.tmp", file_name.to_string_lossy());
    remove_stale_temporaries(&dir, &prefix, ending);
    Ok(dir.join(format!("{prefix}{}{ending}", std::process::id())))
}

/// Removes temporaries of earlier writes to the same path whose process is gone (a kill -9
/// during a write leaves one). Only where /proc tells which processes live; a temporary of a
/// live process (a concurrent write) is left alone.
fn remove_stale_temporaries(dir: &Path, prefix: &str, ending: &str) {
    let proc = Path::new("/proc");
    if !proc.join("self").exists() {
        return;
    }
    let Ok(entries) = std::fs::read_dir(dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(pid) = name
            .to_str()
            .and_then(|n| n.strip_prefix(prefix))
            .and_then(|p| p.strip_suffix(ending))
            .and_then(|p| p.parse::<u32>().ok())
        else {
            continue;
        };
        if pid != std::process::id() && !proc.join(pid.to_string()).exists() {
            let _ = std::fs::remove_file(entry.path());
        }
    }
}

/// What output bytes go to: a file, or a FIFO opened without blocking (see `open_through`).
pub struct Sink {
    file: std::fs::File,
    /// Writes that would block (the FIFO's reader is slower) are retried, not errors.
    retry: bool,
}

impl Sink {
    fn file(file: std::fs::File) -> Sink {
        Sink { file, retry: false }
    }

    pub fn sync_all(&self) -> std::io::Result<()> {
        self.file.sync_all()
    }
}

impl Write for Sink {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        loop {
            match self.file.write(buf) {
                Err(e) if self.retry && e.kind() == std::io::ErrorKind::WouldBlock => {
                    std::thread::sleep(std::time::Duration::from_millis(1))
                }
                result => return result,
            }
        }
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.file.flush()
    }
}

/// Image encoders ask for `Seek`; a file seeks, a FIFO refuses (as the file itself would).
impl std::io::Seek for Sink {
    fn seek(&mut self, pos: std::io::SeekFrom) -> std::io::Result<u64> {
        self.file.seek(pos)
    }
}

/// `O_NONBLOCK` where it is known: opening a FIFO for writing without it waits for a reader
/// forever.
#[cfg(target_os = "linux")]
const O_NONBLOCK: Option<i32> = Some(0o4000);
#[cfg(any(
    target_os = "macos",
    target_os = "ios",
    target_os = "freebsd",
    target_os = "openbsd",
    target_os = "netbsd"
))]
const O_NONBLOCK: Option<i32> = Some(0x0004);
#[cfg(not(any(
    target_os = "linux",
    target_os = "macos",
    target_os = "ios",
    target_os = "freebsd",
    target_os = "openbsd",
    target_os = "netbsd"
)))]
const O_NONBLOCK: Option<i32> = None;

/// Opens an output that is written through (a device, a FIFO, a dangling symlink). A FIFO is
/// opened without blocking, so one without a reader is an error (ENXIO), not a process waiting
/// forever; its writes then wait for the reader instead.
fn open_through(path: &Path) -> std::io::Result<Sink> {
    use std::os::unix::fs::{FileTypeExt, OpenOptionsExt};
    let fifo = std::fs::metadata(path).is_ok_and(|m| m.file_type().is_fifo());
    let mut options = std::fs::OpenOptions::new();
    options.write(true).create(true).truncate(true);
    if let (true, Some(flag)) = (fifo, O_NONBLOCK) {
        options.custom_flags(flag);
        return options
            .open(path)
            .map(|file| Sink { file, retry: true })
            .map_err(|e| {
                std::io::Error::new(
                    e.kind(),
                    format!("a FIFO that nobody reads (start its reader first): {e}"),
                )
            });
    }
    options.open(path).map(Sink::file)
}

/// How an output path is written.
enum Target {
    /// A regular file or a new path (a symlink's target, resolved): temporary + rename.
    Atomic(std::path::PathBuf),
    /// A device, a FIFO or a dangling symlink: opened and written in place.
    Through,
}

fn target(path: &Path) -> Result<Target> {
    let meta = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(Target::Atomic(path.to_path_buf()))
        }
        Err(e) => return Err(Error::io(path, e)),
    };
    let kind = meta.file_type();
    if kind.is_file() {
        Ok(Target::Atomic(path.to_path_buf()))
    } else if kind.is_dir() {
        Err(Error::Invalid(format!(
            "{}: is a folder, not a file",
            path.display()
        )))
    } else if kind.is_symlink() {
        match std::fs::canonicalize(path) {
            // The resolved path is no symlink: one more level at most.
            Ok(real) => target(&real),
            Err(_) => Ok(Target::Through),
        }
    } else {
        Ok(Target::Through)
    }
}

/// Refuses an image name whose extension says another format: images are written as PNG
/// (lossless, so two images compare bit for bit), and a `.jpg` holding PNG bytes misleads every
/// viewer. A name without an extension (a device, a FIFO) is taken.
pub fn check_png_name(option: &str, path: &Path) -> Result<()> {
    if is_standard_output(path) {
        return Err(Error::Invalid(format!(
            "{option} -: images are not written to standard output (only `--json -` is); \
             name a file .png"
        )));
    }
    match path.extension() {
        Some(ext) if !ext.eq_ignore_ascii_case("png") => Err(Error::Invalid(format!(
            "{option} {}: images are written as PNG (lossless, so they compare bit for bit); \
             name the file .png",
            path.display()
        ))),
        _ => Ok(()),
    }
}

/// Refuses a command's outputs that would overwrite one of its inputs or each other (the
/// later write would silently replace the file). `inputs`: files the command reads (paths that
/// are no existing file are ignored: a dataset name, a preset); `outputs`: (option, path).
/// Paths are compared as resolved (symlinks, `..`, a new file by its folder); devices and FIFOs
/// (/dev/null twice) are not files and may repeat.
pub fn check_distinct(inputs: &[&Path], outputs: &[(&str, &Path)]) -> Result<()> {
    let resolve = |path: &Path| -> Option<std::path::PathBuf> {
        match std::fs::metadata(path) {
            Ok(meta) if !meta.is_file() => None,
            Ok(_) => std::fs::canonicalize(path).ok(),
            // A new file, perhaps in folders still to be made: its longest existing ancestor
            // resolved, the rest of the path followed by name.
            Err(_) => {
                let absolute = std::env::current_dir().ok()?.join(path);
                let parts: Vec<_> = absolute.components().collect();
                let (mut real, known) = (1..=parts.len()).rev().find_map(|n| {
                    let prefix: std::path::PathBuf = parts[..n].iter().collect();
                    Some((std::fs::canonicalize(prefix).ok()?, n))
                })?;
                // The rest lexically (its folders do not exist yet: no symlink among them).
                for part in &parts[known..] {
                    match part {
                        std::path::Component::ParentDir => {
                            real.pop();
                        }
                        std::path::Component::Normal(name) => real.push(name),
                        _ => {}
                    }
                }
                Some(real)
            }
        }
    };
    let read: Vec<(&Path, std::path::PathBuf)> = inputs
        .iter()
        .filter(|p| p.is_file())
        .filter_map(|p| Some((*p, resolve(p)?)))
        .collect();
    let mut written: Vec<(&str, std::path::PathBuf)> = Vec::new();
    for &(option, path) in outputs {
        if is_standard_output(path) {
            continue;
        }
        let Some(real) = resolve(path) else { continue };
        if let Some((input, _)) = read.iter().find(|(_, r)| *r == real) {
            return Err(Error::Invalid(format!(
                "{option} {}: is the input {}; writing it would destroy it (choose another name)",
                path.display(),
                input.display()
            )));
        }
        if let Some((other, _)) = written.iter().find(|(_, r)| *r == real) {
            return Err(Error::Invalid(format!(
                "{option} {}: is also the file of {other}; one would overwrite the other (choose \
                 another name)",
                path.display()
            )));
        }
        written.push((option, real));
    }
    Ok(())
}

/// `-` as the path of a JSON output (`--json -`): standard output, as for most command-line
/// tools. The command's text then goes to standard error, so that the JSON can be piped.
pub fn is_standard_output(path: &Path) -> bool {
    path.as_os_str() == "-"
}

/// Fails early, before a long computation, when `path` cannot be written: a folder, or a
/// folder that cannot be created or written into (tried with the temporary the write will
/// use). Devices and FIFOs are not opened here (opening a FIFO waits for its reader). Folders
/// the check makes are removed again: the write makes them when it comes, and a command that
/// fails before it leaves no empty folder behind.
pub fn check_writable(path: &Path) -> Result<()> {
    if is_standard_output(path) {
        return Ok(());
    }
    if let Target::Atomic(real) = target(path)? {
        let parent = match real.parent() {
            Some(p) if !p.as_os_str().is_empty() => p.to_path_buf(),
            _ => std::path::PathBuf::from("."),
        };
        // Made one at a time from the top, so that exactly the folders this check made are
        // removed again (a path through `..` may name a folder that was there before).
        let mut made: Vec<std::path::PathBuf> = Vec::new();
        let mut prefix = std::path::PathBuf::new();
        let mut checked = Ok(());
        for part in parent.components() {
            prefix.push(part);
            if !prefix.exists() {
                match std::fs::create_dir(&prefix) {
                    Ok(()) => made.push(prefix.clone()),
                    // Made by another process meanwhile: not ours to remove.
                    Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
                    Err(e) => {
                        checked = Err(Error::io(&prefix, e));
                        break;
                    }
                }
            }
        }
        if checked.is_ok() {
            checked = temporary_path(&real).and_then(|tmp| {
                std::fs::File::create(&tmp).map_err(|e| Error::io(path, e))?;
                let _ = std::fs::remove_file(&tmp);
                Ok(())
            });
        }
        // Deepest first; a folder something else wrote into meanwhile stays.
        for dir in made.iter().rev() {
            let _ = std::fs::remove_dir(dir);
        }
        checked?;
    }
    Ok(())
}

/// Runs `write`, which may make the folder `dir`; when it fails, a `dir` that did not exist
/// before is removed again if it is empty (a failed command leaves no empty output folder).
pub fn removing_new_folder_on_error<T, E>(
    dir: &Path,
    write: impl FnOnce() -> std::result::Result<T, E>,
) -> std::result::Result<T, E> {
    let existed = dir.exists();
    let result = write();
    if result.is_err() && !existed {
        let _ = std::fs::remove_dir(dir);
    }
    result
}

/// Fails early, before a long computation, when files cannot be written into the folder
/// `dir`, and leaves nothing behind: an existing folder is tried with a temporary file; a
/// missing one by making and removing its first missing folder under the nearest that exists.
pub fn check_folder_writable(dir: &Path) -> Result<()> {
    if dir.is_dir() {
        // Named as a write's temporary, so that one left by a kill is removed by the next.
        let probe = temporary_path(&dir.join("vizsim-write-check"))?;
        std::fs::File::create(&probe).map_err(|e| Error::io(dir, e))?;
        let _ = std::fs::remove_file(&probe);
        return Ok(());
    }
    let mut first_missing = dir.to_path_buf();
    let mut parent = dir.parent();
    while let Some(p) = parent.filter(|p| !p.as_os_str().is_empty() && !p.exists()) {
        first_missing = p.to_path_buf();
        parent = p.parent();
    }
    std::fs::create_dir(&first_missing).map_err(|e| Error::io(dir, e))?;
    let _ = std::fs::remove_dir(&first_missing);
    Ok(())
}

pub fn write_atomically(
    path: &Path,
    write: impl FnOnce(&mut std::io::BufWriter<Sink>) -> std::io::Result<()>,
) -> Result<()> {
    let real = match target(path)? {
        Target::Atomic(real) => real,
        Target::Through => {
            // Errors at the flush (a full disk: /dev/full) are reported, not lost in a drop.
            let result = (|| {
                let mut writer = std::io::BufWriter::new(open_through(path)?);
                write(&mut writer)?;
                writer.flush()
            })();
            return result.map_err(|e| Error::io(path, e));
        }
    };
    let path = real.as_path();
    let tmp = temporary_path(path)?;
    let result = (|| {
        let file = std::fs::File::create(&tmp)?;
        let mut writer = std::io::BufWriter::new(Sink::file(file));
        write(&mut writer)?;
        writer.flush()?;
        writer.get_ref().sync_all()?;
        drop(writer);
        move_into_place(current_scope().as_ref(), &tmp, path)
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(Error::io(path, e));
    }
    Ok(())
}

/// Writes a value as pretty JSON, atomically; to standard output for the path `-`.
pub fn write_json<T: serde::Serialize>(path: &Path, value: &T) -> Result<()> {
    if is_standard_output(path) {
        let mut out = std::io::stdout().lock();
        return serde_json::to_writer_pretty(&mut out, value)
            .map_err(std::io::Error::other)
            .and_then(|()| out.write_all(b"\n"))
            .and_then(|()| out.flush())
            .map_err(|e| Error::io("standard output", e));
    }
    write_atomically(path, |w| {
        serde_json::to_writer_pretty(&mut *w, value).map_err(std::io::Error::other)?;
        w.write_all(b"\n")
    })
}

/// A file written as a stream (waveforms, command traces) under a temporary name in the target's
/// folder, moved to its name only by `commit`: a run that fails or is killed before then leaves
/// no file under the target name, and dropping an uncommitted `PendingFile` removes the
/// temporary. Errors name the target path.
pub struct PendingFile {
    path: std::path::PathBuf,
    /// The temporary renamed to `path` on commit; None when `path` is written through.
    tmp: Option<std::path::PathBuf>,
    writer: std::io::BufWriter<Sink>,
    committed: bool,
    /// The `all_or_none` scope it was created in: its commit renames when the scope ends.
    scope: Option<HeldBack>,
}

impl PendingFile {
    pub fn create(path: &Path) -> Result<PendingFile> {
        let (real, tmp) = match target(path)? {
            Target::Atomic(real) => {
                let tmp = temporary_path(&real)?;
                (real, Some(tmp))
            }
            Target::Through => (path.to_path_buf(), None),
        };
        let file = match &tmp {
            Some(tmp) => std::fs::File::create(tmp).map(Sink::file),
            None => open_through(&real),
        }
        .map_err(|e| Error::io(path, e))?;
        Ok(PendingFile {
            path: real,
            tmp,
            writer: std::io::BufWriter::with_capacity(1 << 18, file),
            committed: false,
            scope: current_scope(),
        })
    }

    /// The name the file gets on `commit`.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Flushes, syncs and renames the file to its name. Writing after this is an error.
    pub fn commit(&mut self) -> Result<()> {
        if self.committed {
            return Err(Error::Invalid(format!(
                "{}: committed twice",
                self.path.display()
            )));
        }
        let result = (|| {
            self.writer.flush()?;
            match &self.tmp {
                Some(tmp) => {
                    self.writer.get_ref().sync_all()?;
                    move_into_place(self.scope.as_ref(), tmp, &self.path)
                }
                None => Ok(()),
            }
        })();
        result.map_err(|e| Error::io(&self.path, e))?;
        self.committed = true;
        Ok(())
    }
}

impl Write for PendingFile {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        if self.committed {
            return Err(std::io::Error::other("file already committed"));
        }
        self.writer.write(buf)
    }

    fn write_all(&mut self, buf: &[u8]) -> std::io::Result<()> {
        if self.committed {
            return Err(std::io::Error::other("file already committed"));
        }
        self.writer.write_all(buf)
    }

    fn flush(&mut self) -> std::io::Result<()> {
        self.writer.flush()
    }
}

impl Drop for PendingFile {
    fn drop(&mut self) {
        if let (false, Some(tmp)) = (self.committed, &self.tmp) {
            let _ = std::fs::remove_file(tmp);
        }
    }
}

/// `arg` as one shell word: as it is when it holds only characters no shell treats specially,
/// else in single quotes. For the commands vizsim prints for the user to run again.
pub fn shell_word(arg: &str) -> String {
    if !arg.is_empty()
        && arg
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || "-_./:=,+".contains(c))
    {
        arg.to_string()
    } else {
        format!("'{}'", arg.replace('\'', r"'\''"))
    }
}

#[cfg(test)]
mod tests {
    use super::shell_word;

    #[test]
    fn words_a_shell_would_split_or_expand_are_quoted() {
        assert_eq!(shell_word("runs/exp-1.toml"), "runs/exp-1.toml");
        assert_eq!(shell_word("my runs"), "'my runs'");
        assert_eq!(shell_word("it's"), r"'it'\''s'");
        assert_eq!(shell_word("$HOME"), "'$HOME'");
        assert_eq!(shell_word(""), "''");
    }
}
