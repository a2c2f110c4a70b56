//! `sysid-io`: writing output files safely — atomically (temporary file in the same folder, then
//! rename), never over one of the run's input files. Shared by the command line, the report and the
//! reproduction pipeline; the libraries that compute never write files. [`Follow`] reads a source that is
//! still being written (`track --follow`).

use std::fmt::Write as _;
use std::io::Write;
use std::path::{Path, PathBuf};

mod cleanup;
mod folder;
pub mod follow;
#[cfg(feature = "parquet")]
pub mod parquet;
pub use folder::{check_folder_path, write_folder};
pub use follow::{Follow, Restarts};

/// Why an output could not be written. Options are named as the caller names them (`flag`).
#[derive(Debug, thiserror::Error)]
pub enum OutputError {
    /// The operating system refused.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// The output path chosen by an option is unusable (a folder, an input file, a missing folder).
    #[error("invalid setting {flag} = {}: {expected}", path.display())]
    Refused {
        /// The option that chose the path, as the caller names it (e.g. `--out`).
        flag: String,
        /// The path.
        path: PathBuf,
        /// What is accepted.
        expected: String,
    },
    /// The output path holds a file of another kind than the output ([`FileKind`]), or is a symbolic
    /// link, and replacing it was not asked for (`--force`).
    #[error(
        "{}: {holds}; this run writes {writes} there, so the file would be lost: refusing to replace it \
         (choose another path, or pass {} to replace it anyway)",
        path.display(),
        force_word()
    )]
    Occupied {
        /// The file concerned, as the user named it.
        path: PathBuf,
        /// What it holds, in words (e.g. "it holds an ipa-sysid-model file (JSON)").
        holds: String,
        /// What the run writes, in words.
        writes: String,
    },
}

/// How the messages name the override of a refusal: the command line's `--force` unless the Python
/// package set its keyword ([`set_force_word`]). The one place these words are chosen (audit s25 L-5:
/// Python's `Model.save` said "not even with --force").
static FORCE_WORD: std::sync::OnceLock<&'static str> = std::sync::OnceLock::new();

/// Names the override in this process's messages (`"force=True"` for the Python package); the first
/// call decides.
pub fn set_force_word(word: &'static str) {
    let _ = FORCE_WORD.set(word);
}

/// The override as the messages name it ([`set_force_word`]; `--force` by default).
pub fn force_word() -> &'static str {
    FORCE_WORD.get().copied().unwrap_or("--force")
}

fn refused(flag: &str, path: &Path, expected: impl Into<String>) -> OutputError {
    OutputError::Refused {
        flag: flag.to_string(),
        path: path.to_path_buf(),
        expected: expected.into(),
    }
}

/// Where an output goes once its path has been looked at ([`resolve_output`]).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum OutputTarget {
    /// `-`: standard output.
    Stdout,
    /// `/dev/null`, a terminal, a FIFO (or a link to one), or another character device with `--force`:
    /// written directly, never replaced. A block device is never an output.
    Stream(PathBuf),
    /// A regular file, new or existing, replaced atomically; a symbolic link is resolved to its target.
    File(PathBuf),
}

/// Looks at the output path `path` (chosen by option `flag`) before anything is written: `-` is standard
/// output; `/dev/null`, a terminal or a FIFO (or a link to one) is written directly, another character
/// device only with `--force`, a block device never (audit s24 H-1); a symbolic link to a regular file
/// is refused unless `--force` was given ([`set_force`]), and then followed (the file it names is
/// replaced, the link stays); a folder, a socket, a link to nothing and a read-only file are refused.
pub fn resolve_output(path: &Path, flag: &str) -> Result<OutputTarget, OutputError> {
    resolve_output_as(path, flag, forced())
}

/// [`resolve_output`] with `force` (`--force`, Python's `force=True`) given by the caller.
pub fn resolve_output_as(
    path: &Path,
    flag: &str,
    force: bool,
) -> Result<OutputTarget, OutputError> {
    if path.as_os_str() == "-" {
        return Ok(OutputTarget::Stdout);
    }
    let link = match std::fs::symlink_metadata(path) {
        Ok(m) => m,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            return Ok(OutputTarget::File(path.to_path_buf()))
        }
        Err(source) => {
            return Err(OutputError::Io {
                path: path.to_path_buf(),
                source,
            })
        }
    };
    // `metadata` follows links: what the link names decides.
    let is_link = link.file_type().is_symlink();
    let meta = if is_link {
        std::fs::metadata(path).map_err(|_| {
            refused(
                flag,
                path,
                "a file name, or a symbolic link to an existing file or device (this link names nothing)",
            )
        })?
    } else {
        link
    };
    let kind = meta.file_type();
    if kind.is_dir() {
        return Err(refused(flag, path, "a file name (this is a folder)"));
    }
    if kind.is_file() {
        if meta.permissions().readonly() {
            return Err(refused(
                flag,
                path,
                "a writable file (this one is read-only; make it writable with chmod u+w, or choose another \
                 path)",
            ));
        }
        let real = if is_link {
            let real = std::fs::canonicalize(path).map_err(|source| OutputError::Io {
                path: path.to_path_buf(),
                source,
            })?;
            if !force {
                return Err(refused(
                    flag,
                    path,
                    format!(
                        "a file name, not a symbolic link (this one names the file {}, which would be \
                         replaced; pass {} to write to it)",
                        real.display(),
                        force_word()
                    ),
                ));
            }
            real
        } else {
            path.to_path_buf()
        };
        return Ok(OutputTarget::File(real));
    }
    if is_socket(&kind) {
        return Err(refused(
            flag,
            path,
            "a file, a device or a FIFO (this is a socket, which cannot be opened as a file)",
        ));
    }
    match device_kind(&meta) {
        Device::Block => {
            return Err(refused(
                flag,
                path,
                format!(
                    "a file, /dev/null, a terminal or a FIFO (this is a block device — a disk or a \
                     partition — whose content the output would overwrite; never written, not even \
                     with {})",
                    force_word()
                ),
            ))
        }
        Device::OtherChar if !force => {
            return Err(refused(
                flag,
                path,
                format!(
                    "a file, /dev/null, a terminal or a FIFO (this is a character device that is \
                     neither; writing into it may change a device's state: pass {} to write into it \
                     anyway)",
                    force_word()
                ),
            ))
        }
        _ => {}
    }
    Ok(OutputTarget::Stream(path.to_path_buf()))
}

/// What kind of device an output path (already known not to be a regular file, folder or socket) is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Device {
    /// A FIFO (a named pipe; `/dev/stdout` of a pipeline), or not a device.
    Fifo,
    /// `/dev/null`, `/dev/zero`, `/dev/full` (writes discarded or refused) or a terminal (the console, a
    /// pseudo-terminal): written into harmlessly.
    Harmless,
    /// Another character device (`/dev/mem`, a serial port, …): written into only with `--force`.
    OtherChar,
    /// A block device (a disk, a partition, a loop device): never written (audit s24 H-1: `simulate --out
    /// /dev/loop0` overwrote the disk image's first sector).
    Block,
}

#[cfg(unix)]
fn device_kind(meta: &std::fs::Metadata) -> Device {
    use std::os::unix::fs::{FileTypeExt, MetadataExt};
    let kind = meta.file_type();
    if kind.is_block_device() {
        return Device::Block;
    }
    if !kind.is_char_device() {
        return Device::Fifo;
    }
    // Linux's device numbers (Documentation/admin-guide/devices.txt): 1:3 /dev/null, 1:5 /dev/zero,
    // 1:7 /dev/full (not 1:1 /dev/mem, 1:2 /dev/kmem, 1:4 /dev/port); major 4 the
    // virtual consoles and serial ttys' 4:0-63, 5:0 /dev/tty, 5:1 /dev/console, 136-143 the
    // pseudo-terminals (/dev/pts/N). The split of dev_t follows glibc's gnu_dev_major/minor.
    let rdev = meta.rdev();
    let major = ((rdev >> 8) & 0xfff) | ((rdev >> 32) & !0xfff);
    let minor = (rdev & 0xff) | ((rdev >> 12) & !0xff);
    let harmless = matches!((major, minor), (1, 3) | (1, 5) | (1, 7) | (5, 0) | (5, 1))
        || (major == 4 && minor < 64)
        || (136..=143).contains(&major);
    if harmless {
        Device::Harmless
    } else {
        Device::OtherChar
    }
}

#[cfg(not(unix))]
fn device_kind(_meta: &std::fs::Metadata) -> Device {
    Device::Fifo
}

/// Whether `path` names a FIFO (a symbolic link is followed).
#[cfg(unix)]
fn is_fifo(path: &Path) -> bool {
    use std::os::unix::fs::FileTypeExt;
    std::fs::metadata(path).is_ok_and(|m| m.file_type().is_fifo())
}

#[cfg(not(unix))]
fn is_fifo(_path: &Path) -> bool {
    false
}

/// Writes `bytes` into the FIFO `path` without blocking ([`write_all_atomic_waiting`]): opened with
/// `O_NONBLOCK` (which fails with ENXIO while no reader has it open), written piece by piece (a full
/// pipe says `WouldBlock`); `keep_waiting` is called before each pause of [`FIFO_POLL`].
#[cfg(unix)]
fn write_fifo_waiting(
    path: &Path,
    bytes: &[u8],
    keep_waiting: &mut dyn FnMut() -> std::io::Result<()>,
) -> std::io::Result<()> {
    use std::os::unix::fs::OpenOptionsExt;
    let mut f = loop {
        match std::fs::OpenOptions::new()
            .write(true)
            .custom_flags(libc::O_NONBLOCK)
            .open(path)
        {
            Ok(f) => break f,
            Err(e) if e.raw_os_error() == Some(libc::ENXIO) => {
                keep_waiting()?;
                std::thread::sleep(FIFO_POLL);
            }
            Err(e) => return Err(e),
        }
    };
    let mut rest = bytes;
    while !rest.is_empty() {
        match f.write(rest) {
            Ok(0) => return Err(std::io::ErrorKind::WriteZero.into()),
            Ok(k) => rest = rest.get(k..).unwrap_or_default(),
            Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => {
                keep_waiting()?;
                std::thread::sleep(FIFO_POLL);
            }
            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
            Err(e) => return Err(e),
        }
    }
    Ok(())
}

#[cfg(not(unix))]
fn write_fifo_waiting(
    path: &Path,
    bytes: &[u8],
    _keep_waiting: &mut dyn FnMut() -> std::io::Result<()>,
) -> std::io::Result<()> {
    std::fs::OpenOptions::new()
        .write(true)
        .open(path)?
        .write_all(bytes)
}

#[cfg(unix)]
fn is_socket(kind: &std::fs::FileType) -> bool {
    use std::os::unix::fs::FileTypeExt;
    kind.is_socket()
}

#[cfg(not(unix))]
fn is_socket(_kind: &std::fs::FileType) -> bool {
    false
}

/// Writes `bytes` to `path`, as [`resolve_output`] decides: standard output for `-`, directly into a
/// device or FIFO (`/dev/null`, a named pipe; never replaced by a file), and atomically into a regular
/// file: the content goes to a temporary file beside it (flushed to disk), which is then renamed over
/// it, so a crash or a failed run never leaves a half-written file and an existing file is either
/// untouched or entirely replaced. A symbolic link is followed: the file it names is replaced, the link
/// stays.
///
/// The new file gets the permissions and the owner of the file it replaces (when the owner cannot be
/// kept, e.g. a file of another user, nothing is written and the error says why), or the usual
/// permissions for a new file (0o666 less the umask) — not the 0o600 of a bare temporary file. While
/// the temporary file exists it is listed for [`remove_temporaries_on_signals`].
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), OutputError> {
    write_all_atomic(&[(path, bytes)]).map(|_| ())
}

/// Whether `--force` was given: an existing file of another kind may be replaced and a symbolic link
/// written through ([`set_force`]).
static FORCE: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

/// Records the command line's `--force` for every later [`write_atomic`], [`write_all_atomic`],
/// [`resolve_output`] and [`check_writable`] of the process. Without it an existing regular file is
/// replaced only by an output of the same [`FileKind`], and a symbolic link to a file is refused.
pub fn set_force(on: bool) {
    FORCE.store(on, std::sync::atomic::Ordering::Relaxed);
}

/// Whether `--force` was recorded ([`set_force`]).
pub fn forced() -> bool {
    FORCE.load(std::sync::atomic::Ordering::Relaxed)
}

/// What a file holds, as far as replacing it is concerned: an existing regular file is replaced (without
/// `--force`) only by an output of the same kind — a model file by a model file, a CSV table by a CSV
/// table with the same header row — so that a run never turns a user's file into something else
/// (audit s22 M-B9). Read from the first [`KIND_HEAD`] bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum FileKind {
    /// Nothing, or only white space: nothing is lost by replacing it.
    Empty,
    /// A JSON object with a top-level `"format"` key (`ipa-sysid-model`, `ipa-sysid-controller`, ...;
    /// [`sysid_core::data::json_format_key`]'s rule, within the first [`KIND_HEAD`] bytes).
    Format(String),
    /// Other JSON: not an output of ipa-sysid (a `package.json`, a notebook, a configuration), or a
    /// `--json` report of a version before reports carried their [`REPORT_FORMAT`] mark (audit s32 H-1:
    /// any JSON without a `"format"` key was taken for a report and replaced).
    Json,
    /// An HTML page written by ipa-sysid (its `<meta name="generator" content="ipa-sysid …">`, which
    /// the report writes in its head).
    Html,
    /// Another HTML page (audit s32 H-1: `fleet.report(results, "notebook.html")` replaced a hand-written
    /// page).
    OtherHtml,
    /// An SVG picture.
    Svg,
    /// A PNG picture.
    Png,
    /// A Parquet file.
    Parquet,
    /// A plant TOML written by ipa-sysid (`plant-config`, a `calibrate` twin): its first line is a
    /// comment naming ipa-sysid (and the record, which may differ between two runs).
    PlantToml,
    /// Other text, known by its first line: a CSV table's header row, the twin TOML's header comment.
    Text(String),
    /// Other bytes (not UTF-8, or with NUL bytes).
    Binary,
}

pub use sysid_core::data::REPORT_FORMAT;

/// How many bytes of a file [`FileKind::of`] looks at.
pub const KIND_HEAD: usize = 64 * 1024;

impl FileKind {
    /// The kind of a file that begins with `head` (its first bytes; [`KIND_HEAD`] are enough).
    pub fn of(head: &[u8]) -> Self {
        let head = head.strip_prefix(b"\xEF\xBB\xBF").unwrap_or(head);
        if head.starts_with(b"\x89PNG\r\n\x1a\n") {
            return Self::Png;
        }
        if head.starts_with(b"PAR1") {
            return Self::Parquet;
        }
        if head.contains(&0) {
            return Self::Binary;
        }
        // A multi-byte character cut at the end of `head` is still text.
        let text = match std::str::from_utf8(head) {
            Ok(t) => t,
            Err(e) if e.error_len().is_none() => {
                std::str::from_utf8(&head[..e.valid_up_to()]).unwrap_or_default()
            }
            Err(_) => return Self::Binary,
        };
        let body = text.trim_start();
        if body.is_empty() {
            return Self::Empty;
        }
        if body.starts_with('{') {
            return match sysid_core::data::json_format_key(body) {
                Some(f) => Self::Format(f),
                None => Self::Json,
            };
        }
        if body.starts_with('[') {
            return Self::Json;
        }
        let lower: String = body
            .chars()
            .take(15)
            .collect::<String>()
            .to_ascii_lowercase();
        if lower.starts_with("<!doctype html") || lower.starts_with("<html") {
            // The report's own mark (the report crate's head: `<meta name="generator" content="ipa-sysid …`).
            let mine = text.contains("<meta name=\"generator\" content=\"ipa-sysid");
            return if mine { Self::Html } else { Self::OtherHtml };
        }
        if lower.starts_with("<svg") || (lower.starts_with("<?xml") && text.contains("<svg")) {
            return Self::Svg;
        }
        let line = text.lines().next().unwrap_or_default();
        if line.starts_with('#') && line.contains("ipa-sysid") {
            return Self::PlantToml;
        }
        Self::Text(line.trim_end_matches('\r').to_string())
    }

    /// The kind of the existing regular file `path` ([`FileKind::of`] its first [`KIND_HEAD`] bytes).
    pub fn of_file(path: &Path) -> std::io::Result<Self> {
        use std::io::Read;
        let mut head = Vec::new();
        std::fs::File::open(path)?
            .take(KIND_HEAD as u64)
            .read_to_end(&mut head)?;
        Ok(Self::of(&head))
    }

    /// Whether an output of this kind may replace a file of kind `old` without `--force`: the same
    /// kind (text: the same first line), or an empty file.
    pub fn may_replace(&self, old: &FileKind) -> bool {
        *old == FileKind::Empty || self == old
    }

    /// Whether a file of this kind is told from a user's file of the same kind only by the
    /// [`OUTPUT_MARK`] attribute: a CSV table or other text (known by its first line alone, which a
    /// measured record may share with an output: `t,r,u,y` is `control --out`'s header and a
    /// closed-loop log's), an SVG, PNG or Parquet file. The other kinds carry their own mark in their
    /// content (a model's `"format"` key, the report's generator tag, the twin TOML's first comment).
    pub fn known_by_mark(&self) -> bool {
        matches!(self, Self::Text(_) | Self::Svg | Self::Png | Self::Parquet)
    }

    /// The kind in words, e.g. "an ipa-sysid-model file (JSON)", "a CSV table with header t,u,y".
    pub fn describe(&self) -> String {
        match self {
            Self::Empty => "an empty file".into(),
            Self::Format(f) => format!("an {} file (JSON)", shown(f)),
            Self::Json => format!(
                "a JSON document that is not an ipa-sysid output (no \"format\" key; a report of \
                 this tool carries \"format\": \"{REPORT_FORMAT}\", one of a version before \
                 2026-11-29 does not)"
            ),
            Self::Html => "an HTML page written by ipa-sysid".into(),
            Self::OtherHtml => "an HTML page not written by ipa-sysid".into(),
            Self::Svg => "an SVG picture".into(),
            Self::Png => "a PNG picture".into(),
            Self::Parquet => "a Parquet file".into(),
            Self::PlantToml => {
                "a plant TOML written by ipa-sysid (plant-config or calibrate)".into()
            }
            Self::Text(line) if line.contains(',') || line.contains(';') || line.contains('\t') => {
                format!("a CSV table with header {}", shown(line))
            }
            Self::Text(line) => format!("text beginning \"{}\"", shown(line)),
            Self::Binary => "binary data".into(),
        }
    }
}

/// `s` for a message: made safe to print ([`sysid_core::format::visible`]), at most 80 characters.
fn shown(s: &str) -> String {
    let cut: String = s.chars().take(80).collect();
    let more = if cut.len() < s.len() { "..." } else { "" };
    format!("{}{more}", sysid_core::format::visible(&cut))
}

/// Refuses (without `force`) to replace the existing regular file `real` (named `path` by the user) by
/// `bytes` when the two are not of the same [`FileKind`]; `Ok(true)` when a file is there (and will be
/// replaced), `Ok(false)` when the path is free.
fn check_replace(path: &Path, real: &Path, bytes: &[u8], force: bool) -> Result<bool, OutputError> {
    let new = FileKind::of(&bytes[..bytes.len().min(KIND_HEAD)]);
    check_replace_kind(path, real, &new, force)
}

/// Before any work: refuses (without `--force`) an output path that holds a regular file an output of
/// kind `new` may not replace ([`FileKind::may_replace`]), with the words [`write_all_atomic`] would use
/// at the end (audit s28 M-3: `calibrate --out user.txt` ran its whole search before refusing). A
/// command whose output's kind is known before it computes calls this beside
/// [`check_writable`]; the write checks again.
pub fn check_replaceable(path: &Path, new: &FileKind) -> Result<(), OutputError> {
    if path.as_os_str() == "-" {
        return Ok(());
    }
    check_replace_kind(path, path, new, forced()).map(|_| ())
}

/// [`check_replace`] for an output of kind `new`.
fn check_replace_kind(
    path: &Path,
    real: &Path,
    new: &FileKind,
    force: bool,
) -> Result<bool, OutputError> {
    match std::fs::metadata(real) {
        Ok(m) if m.is_file() => {}
        _ => return Ok(false),
    }
    if force {
        return Ok(true);
    }
    let old = FileKind::of_file(real).map_err(|source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if new.may_replace(&old) {
        if old.known_by_mark() && output_mark(real) == Mark::Unmarked {
            // The same kind, but not written by ipa-sysid: a measured record kept with exactly an
            // output's header row (session 32's caveat), a user's picture.
            return Err(OutputError::Occupied {
                path: path.to_path_buf(),
                holds: format!(
                    "it holds {} that ipa-sysid did not write (the file has no `{OUTPUT_MARK}` \
                     extended attribute, which every output of ipa-sysid carries: a measured record, \
                     a copy, an edited file, or an output of a version before 2026-11-29)",
                    old.describe()
                ),
                writes: new.describe(),
            });
        }
        return Ok(true);
    }
    Err(OutputError::Occupied {
        path: path.to_path_buf(),
        holds: format!("it holds {}", old.describe()),
        writes: new.describe(),
    })
}

/// Writes several outputs of one run together, each as [`write_atomic`] writes it, so that a failure
/// of any leaves every existing output as it was (audit s14 M-f: a full disk for `--json` left `--out`
/// replaced): every regular file is first written to its temporary file (flushed); then the devices,
/// FIFOs and standard output are written; only when all of that succeeded are the temporary files
/// renamed into place, in order. A rename can still fail after an earlier one succeeded (the folder
/// removed meanwhile, say): then the error says which outputs were already replaced.
///
/// An existing regular file is replaced only by an output of the same [`FileKind`] (or when empty), and
/// a symbolic link to a file is refused, unless `--force` ([`set_force`]); nothing is written when any
/// output is refused. Returns the outputs (as named by the caller) that replaced an existing file.
pub fn write_all_atomic(outputs: &[(&Path, &[u8])]) -> Result<Vec<PathBuf>, OutputError> {
    write_all_atomic_as(outputs, forced())
}

/// [`write_all_atomic`] with `force` given by the caller (Python's `force=True`).
pub fn write_all_atomic_as(
    outputs: &[(&Path, &[u8])],
    force: bool,
) -> Result<Vec<PathBuf>, OutputError> {
    write_all_atomic_waiting(outputs, force, None)
}

/// How often [`write_all_atomic_waiting`] calls its `keep_waiting` while a FIFO has no reader or its
/// pipe is full.
const FIFO_POLL: std::time::Duration = std::time::Duration::from_millis(10);

/// [`write_all_atomic_as`] for a caller that must stay interruptible while a FIFO output waits: with
/// `keep_waiting`, a FIFO is opened and written without blocking, and while it has no reader (opening
/// it would block) or its pipe is full (writing would block) `keep_waiting` is called about every
/// 10 ms; an error from it ends the wait, nothing more is written to that FIFO, no temporary file is
/// renamed into place, and the error is returned (as [`OutputError::Io`] naming the FIFO). Python passes
/// its signal check, so Ctrl-C or an alarm handler's exception ends a `Model.save` into a FIFO nobody
/// reads (audit s25: the blocking open is restarted after every signal, and the handler never ran).
/// The command line passes `None`: a FIFO blocks as any Unix tool's output, and a signal ends the
/// process. Devices and standard output are written as [`write_all_atomic_as`] writes them.
pub fn write_all_atomic_waiting(
    outputs: &[(&Path, &[u8])],
    force: bool,
    mut keep_waiting: Option<&mut dyn FnMut() -> std::io::Result<()>>,
) -> Result<Vec<PathBuf>, OutputError> {
    let mut targets = Vec::new();
    let mut replaced = Vec::new();
    for &(path, bytes) in outputs {
        let io = |source| OutputError::Io {
            path: path.to_path_buf(),
            source,
        };
        let target = match resolve_output_as(path, "output", force) {
            Ok(t) => t,
            Err(OutputError::Refused { expected, .. }) => {
                return Err(io(std::io::Error::other(format!("expected {expected}"))))
            }
            Err(e) => return Err(e),
        };
        if let OutputTarget::File(p) = &target {
            if check_replace(path, p, bytes, force)? {
                replaced.push(path.to_path_buf());
            }
        }
        targets.push((target, bytes));
    }
    let mut staged = Vec::new();
    let mut direct = Vec::new();
    for (target, bytes) in targets {
        match target {
            OutputTarget::File(p) => staged.push(stage(&p, bytes)?),
            OutputTarget::Stdout => direct.push((None, bytes)),
            OutputTarget::Stream(p) => direct.push((Some(p), bytes)),
        }
    }
    // Devices, FIFOs (`Some`) and standard output (`None`).
    for (target, bytes) in direct {
        match target {
            None => {
                let mut out = std::io::stdout().lock();
                out.write_all(bytes)
                    .and_then(|()| out.flush())
                    .map_err(|source| OutputError::Io {
                        path: PathBuf::from("<standard output>"),
                        source,
                    })?;
            }
            Some(p) => {
                let io = |source| OutputError::Io {
                    path: p.clone(),
                    source,
                };
                if let (Some(wait), true) = (keep_waiting.as_deref_mut(), is_fifo(&p)) {
                    write_fifo_waiting(&p, bytes, wait).map_err(io)?;
                    continue;
                }
                let mut f = std::fs::OpenOptions::new()
                    .write(true)
                    .open(&p)
                    .map_err(io)?;
                f.write_all(bytes).and_then(|()| f.flush()).map_err(io)?;
            }
        }
    }
    // Every rename of the run with the signal list locked (audit s36 M-1: a signal between two
    // renames left the new --json beside the old --save-model): a signal comes before them all (every
    // temporary removed, every output as it was) or after them all. The folders are synced after.
    let (result, dirs) = cleanup::locked(|list| {
        let mut done: Vec<PathBuf> = Vec::new();
        let mut dirs: Vec<PathBuf> = Vec::new();
        let mut staged = staged.into_iter();
        while let Some(s) = staged.next() {
            let path = s.path.clone();
            if let Err(source) = s.pending.persist_locked(list, s.tmp, &s.path) {
                for rest in staged.by_ref() {
                    rest.pending.discard_locked(list, rest.tmp);
                }
                let source = if done.is_empty() {
                    source
                } else {
                    std::io::Error::new(
                        source.kind(),
                        format!(
                            "{source} (already replaced: {})",
                            done.iter()
                                .map(|p| p.display().to_string())
                                .collect::<Vec<_>>()
                                .join(", ")
                        ),
                    )
                };
                return (
                    Err(OutputError::Io {
                        path: cleanup::shown_path(&path),
                        source,
                    }),
                    dirs,
                );
            }
            let dir = parent_dir(&path).to_path_buf();
            if !dirs.contains(&dir) {
                dirs.push(dir);
            }
            done.push(path);
        }
        (Ok(()), dirs)
    });
    // The renames made durable where the platform can.
    for dir in dirs {
        if let Ok(d) = std::fs::File::open(&dir) {
            let _ = d.sync_all();
        }
    }
    result?;
    Ok(replaced)
}

/// A regular-file output written to its temporary file beside it, not yet renamed into place; dropped
/// without [`Staged::commit`], the temporary file is removed.
struct Staged {
    tmp: tempfile::NamedTempFile,
    pending: cleanup::Pending,
    path: PathBuf,
}

/// Writes `bytes` to a temporary file beside `path` (flushed to disk), with the permissions and owner of
/// the file it will replace ([`write_atomic`]).
fn stage(path: &Path, bytes: &[u8]) -> Result<Staged, OutputError> {
    // Named as the user named it (inside an output folder: the folder's final path), without the
    // hidden temporary's path that `tempfile` appends (audit s36 L-1).
    let io = |source| OutputError::Io {
        path: cleanup::shown_path(path),
        source: without_temp_path(source),
    };
    let dir = parent_dir(path);
    let mut builder = tempfile::Builder::new();
    builder.prefix(TEMP_PREFIX).suffix(".tmp");
    let existing = std::fs::metadata(path).ok().filter(|m| m.is_file());
    let permissions = match &existing {
        Some(m) => Some(m.permissions()),
        None => default_permissions(),
    };
    if let Some(p) = permissions {
        builder.permissions(p);
    }
    let (mut tmp, pending) = cleanup::Pending::create(&builder, dir).map_err(io)?;
    if let Some(m) = &existing {
        keep_owner(tmp.as_file(), m).map_err(io)?;
    }
    tmp.write_all(bytes).map_err(io)?;
    set_output_mark(tmp.as_file());
    tmp.as_file().sync_all().map_err(io)?;
    Ok(Staged {
        tmp,
        pending,
        path: path.to_path_buf(),
    })
}

/// The extended attribute every regular file ipa-sysid writes carries (value `output`), set on the
/// temporary file before it is renamed into place. A file of a kind known only by its first line or
/// its format ([`FileKind::known_by_mark`]: a CSV table, an SVG, a PNG) is replaced without `--force`
/// only when it carries this mark, so a measured record whose header row is exactly an output's
/// (`control --out`'s `t,r,u,y`) is not taken for an earlier output. Where the file system keeps no
/// user extended attributes (the mark cannot be read or set: [`Mark::Unknown`]), the rule falls back to
/// the kind alone (docs/reliability.md). Linux only; elsewhere [`Mark::Unknown`] always. Written with
/// `libc`'s `fsetxattr`/`getxattr` (two calls; the `xattr` crate would add a dependency for them).
pub const OUTPUT_MARK: &str = "user.ipa-sysid";

/// Whether an existing file carries [`OUTPUT_MARK`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mark {
    /// It does: an output of ipa-sysid (or a copy made with its extended attributes).
    Marked,
    /// The file system keeps extended attributes and this file has none named so.
    Unmarked,
    /// Not known (the file system keeps no user extended attributes, or another error, or not Linux).
    Unknown,
}

/// Whether the file `path` (a symbolic link followed) carries [`OUTPUT_MARK`].
#[cfg(target_os = "linux")]
pub fn output_mark(path: &Path) -> Mark {
    use std::os::unix::ffi::OsStrExt;
    let (Ok(p), Ok(name)) = (
        std::ffi::CString::new(path.as_os_str().as_bytes()),
        std::ffi::CString::new(OUTPUT_MARK),
    ) else {
        return Mark::Unknown;
    };
    // SAFETY: two NUL-terminated strings that live across the call; a null buffer of size 0 asks for
    // the value's size only.
    let n = unsafe { libc::getxattr(p.as_ptr(), name.as_ptr(), std::ptr::null_mut(), 0) };
    if n >= 0 {
        return Mark::Marked;
    }
    match std::io::Error::last_os_error().raw_os_error() {
        Some(libc::ENODATA) => Mark::Unmarked,
        _ => Mark::Unknown,
    }
}

/// Whether the file `path` carries [`OUTPUT_MARK`]: not known off Linux.
#[cfg(not(target_os = "linux"))]
pub fn output_mark(_path: &Path) -> Mark {
    Mark::Unknown
}

/// Sets [`OUTPUT_MARK`] on `file`; a file system that keeps no such attribute is not an error (the
/// replacement rule then falls back to the kind: [`Mark::Unknown`]).
#[cfg(target_os = "linux")]
fn set_output_mark(file: &std::fs::File) {
    use std::os::fd::AsRawFd;
    let Ok(name) = std::ffi::CString::new(OUTPUT_MARK) else {
        return;
    };
    let value = b"output";
    // SAFETY: a valid open descriptor, a NUL-terminated name and a buffer of `value.len()` bytes.
    let _ = unsafe {
        libc::fsetxattr(
            file.as_raw_fd(),
            name.as_ptr(),
            value.as_ptr().cast(),
            value.len(),
            0,
        )
    };
}

#[cfg(not(target_os = "linux"))]
fn set_output_mark(_file: &std::fs::File) {}

/// The prefix of the temporary files [`write_atomic`] creates beside its outputs (`.ipa-sysid-*.tmp`).
pub const TEMP_PREFIX: &str = ".ipa-sysid-";

/// Gives the new file `file` the owner and group of the file it replaces (`old`), or says why it cannot.
#[cfg(unix)]
fn keep_owner(file: &std::fs::File, old: &std::fs::Metadata) -> std::io::Result<()> {
    use std::os::unix::fs::MetadataExt;
    let new = file.metadata()?;
    if new.uid() == old.uid() && new.gid() == old.gid() {
        return Ok(());
    }
    std::os::unix::fs::fchown(file, Some(old.uid()), Some(old.gid())).map_err(|e| {
        std::io::Error::new(
            e.kind(),
            format!(
                "the file belongs to user {} group {} and replacing it would give it to user {} group {} \
                 ({e}); write elsewhere, or as its owner",
                old.uid(),
                old.gid(),
                new.uid(),
                new.gid()
            ),
        )
    })
}

#[cfg(not(unix))]
fn keep_owner(_file: &std::fs::File, _old: &std::fs::Metadata) -> std::io::Result<()> {
    Ok(())
}

pub use cleanup::{
    accept_stop, remove_temporaries_on_signals, spawn_listed, stop_asked, ListedChild, ScratchDir,
    CHILD_GRACE,
};

/// Writes a CSV table to `path` atomically ([`write_atomic`]) through `csv::Writer` (fields quoted
/// only where needed, `\n` line ends): the `header` row, then every row of `rows`, whose cells the
/// caller has already formatted.
pub fn write_csv<R, C>(path: &Path, header: &[&str], rows: R) -> Result<(), OutputError>
where
    R: IntoIterator,
    R::Item: IntoIterator<Item = C>,
    C: AsRef<[u8]>,
{
    write_atomic(path, &csv_bytes(path, header, rows)?)
}

/// The bytes [`write_csv`] writes (for outputs written together: [`write_all_atomic`]); `path` names
/// the output in messages.
pub fn csv_bytes<R, C>(path: &Path, header: &[&str], rows: R) -> Result<Vec<u8>, OutputError>
where
    R: IntoIterator,
    R::Item: IntoIterator<Item = C>,
    C: AsRef<[u8]>,
{
    let io = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(header).map_err(|e| io(e.into()))?;
    for row in rows {
        w.write_record(row).map_err(|e| io(e.into()))?;
    }
    w.into_inner().map_err(|e| io(e.into_error()))
}

/// `x` as [`sysid_core::format::Shortest`] prints it (the shortest decimal that reads back as the same
/// f64, in exponent form below 1e-5 and from 1e16 in magnitude), without the general formatter's cost
/// for the common case of a record ([`push_shortest`]).
pub fn format_shortest(x: f64) -> String {
    let mut out = String::with_capacity(16);
    push_shortest(&mut out, x);
    out
}

/// Appends `x` as [`sysid_core::format::Shortest`] prints it to `out`. Fast path for values with at most three decimals and
/// |x| < 1e9 (sample times, integer commands, encoder counts): for the smallest d in 0..=3 such that
/// n / 10^d == x with n = round(x 10^d), the decimal n · 10^-d reads back as x (the division and the
/// parser both round the same exact quotient correctly), and it is the only one with d decimals
/// (their spacing, 10^-d, far exceeds the spacing of f64 below 1e9), so it is the shortest. Every
/// other value goes through [`sysid_core::format::Shortest`].
pub fn push_shortest(out: &mut String, x: f64) {
    const SCALE: [f64; 4] = [1.0, 10.0, 100.0, 1000.0];
    if x != 0.0 && x.abs() < 1e9 {
        for (d, &scale) in SCALE.iter().enumerate() {
            let n = (x * scale).round();
            if n / scale == x {
                if n < 0.0 {
                    out.push('-');
                }
                let m = n.abs() as u64;
                let p = 10u64.pow(d as u32);
                let mut digits = itoa::Buffer::new();
                out.push_str(digits.format(m / p));
                if d > 0 {
                    out.push('.');
                    let frac = digits.format(m % p);
                    out.extend(std::iter::repeat_n('0', d - frac.len()));
                    out.push_str(frac);
                }
                return;
            }
        }
    }
    // Writing to a String cannot fail.
    let _ = write!(out, "{}", sysid_core::format::Shortest(x));
}

/// `x` with one decimal, exactly as `format!("{x:.1}")` ([`push_one_decimal`]).
pub fn format_one_decimal(x: f64) -> String {
    let mut out = String::with_capacity(16);
    push_one_decimal(&mut out, x);
    out
}

/// Appends `x` with one decimal to `out`, exactly as `{:.1}` (the decimal nearest to the exact binary
/// value, ties to even) but without the general formatter's cost for the common case: for 0 <= x <
/// 1e12 whose tenths are not within 1e-3 of a tie, the rounded product 10 x (off the exact one by at
/// most 1.2e-4) rounds to the same integer, printed with a decimal point; every other value (negative,
/// -0, NaN, huge) goes through `{:.1}`.
pub fn push_one_decimal(out: &mut String, x: f64) {
    let q = x * 10.0;
    if x.is_sign_positive() && x < 1e12 && (q - q.floor() - 0.5).abs() > 1e-3 {
        let n = q.round() as u64;
        out.push_str(itoa::Buffer::new().format(n / 10));
        out.push('.');
        out.push(char::from(b'0' + (n % 10) as u8));
    } else {
        let _ = write!(out, "{x:.1}");
    }
}

/// How [`write_formatted_columns_csv`] prints the numbers of a column.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NumberFormat {
    /// The shortest decimal that reads back as the same f64 ([`push_shortest`]).
    Shortest,
    /// `{:.1}`: one decimal ([`push_one_decimal`]).
    OneDecimal,
}

impl NumberFormat {
    /// Appends `x` in this format to `out`.
    pub fn push(self, out: &mut String, x: f64) {
        match self {
            NumberFormat::Shortest => push_shortest(out, x),
            NumberFormat::OneDecimal => push_one_decimal(out, x),
        }
    }
}

/// Writes equally long columns of numbers as a CSV table to `path` atomically ([`write_csv`]): the
/// `header` row, then row k holds `columns[j][k]` for every j, each printed with Rust's `{}` (the
/// shortest decimal that reads back as the same f64). Fails, writing nothing, when the header and the
/// columns differ in number or the columns in length.
pub fn write_columns_csv(
    path: &Path,
    header: &[&str],
    columns: &[&[f64]],
) -> Result<(), OutputError> {
    write_atomic(path, &columns_csv(path, header, columns)?)
}

/// The bytes [`write_columns_csv`] writes (for outputs written together: [`write_all_atomic`]); `path`
/// names the output in messages.
pub fn columns_csv(
    path: &Path,
    header: &[&str],
    columns: &[&[f64]],
) -> Result<Vec<u8>, OutputError> {
    let formatted: Vec<(&[f64], NumberFormat)> = columns
        .iter()
        .map(|&c| (c, NumberFormat::Shortest))
        .collect();
    formatted_columns_csv(path, header, &formatted)
}

/// [`write_columns_csv`] with a [`NumberFormat`] per column; the cells are formatted into buffers
/// reused from row to row (no allocation per row), and written through `csv::Writer` as
/// [`write_csv`] does.
pub fn write_formatted_columns_csv(
    path: &Path,
    header: &[&str],
    columns: &[(&[f64], NumberFormat)],
) -> Result<(), OutputError> {
    write_atomic(path, &formatted_columns_csv(path, header, columns)?)
}

/// The bytes [`write_formatted_columns_csv`] writes (for outputs written together:
/// [`write_all_atomic`]); `path` names the output in messages.
pub fn formatted_columns_csv(
    path: &Path,
    header: &[&str],
    columns: &[(&[f64], NumberFormat)],
) -> Result<Vec<u8>, OutputError> {
    let n = columns.first().map_or(0, |c| c.0.len());
    if header.len() != columns.len() || columns.iter().any(|c| c.0.len() != n) {
        return Err(OutputError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(
                std::io::ErrorKind::InvalidInput,
                format!(
                    "{} header names for {} columns of lengths {:?}; expected one name per column and columns of equal length",
                    header.len(),
                    columns.len(),
                    columns.iter().map(|c| c.0.len()).collect::<Vec<_>>()
                ),
            ),
        });
    }
    let io = |source| OutputError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut w = csv::Writer::from_writer(Vec::with_capacity(n * columns.len() * 12 + 64));
    w.write_record(header).map_err(|e| io(e.into()))?;
    let mut cells = vec![String::new(); columns.len()];
    for k in 0..n {
        for (cell, &(column, format)) in cells.iter_mut().zip(columns) {
            cell.clear();
            format.push(cell, column[k]);
        }
        w.write_record(&cells).map_err(|e| io(e.into()))?;
    }
    w.into_inner().map_err(|e| io(e.into_error()))
}

#[cfg(unix)]
fn default_permissions() -> Option<std::fs::Permissions> {
    use std::os::unix::fs::PermissionsExt;
    Some(std::fs::Permissions::from_mode(0o666)) // the umask applies on creation
}

#[cfg(not(unix))]
fn default_permissions() -> Option<std::fs::Permissions> {
    None
}

/// Refuses to write `output` when it is the same file as any of `inputs` (compared after resolving
/// links, so `./a.csv` and `a.csv` are the same file). A device or FIFO output (`/dev/null`) is written,
/// not replaced, so it is never refused.
pub fn refuse_overwrite_input(
    output: &Path,
    inputs: &[&Path],
    flag: &str,
) -> Result<(), OutputError> {
    if std::fs::metadata(output).is_ok_and(|m| !m.is_file()) {
        return Ok(());
    }
    let canon = |p: &Path| std::fs::canonicalize(p).ok();
    if let Some(out) = canon(output) {
        for input in inputs {
            if canon(input).as_deref() == Some(out.as_path()) {
                return Err(refused(
                    flag,
                    output,
                    "an output path different from every input file (refusing to overwrite your data)",
                ));
            }
        }
    }
    Ok(())
}

/// Checks before any work that `output` can be written ([`resolve_output`]): `-`, a device or FIFO, or a
/// writable file (or link to one) in an existing folder in which this process can create a file (a
/// trial temporary is created there and removed: the honest test, which also sees a read-only file
/// system and access control lists; audit s36 L-1: a read-only folder was found after the whole run);
/// `flag` names the option in messages.
pub fn check_writable(output: &Path, flag: &str) -> Result<(), OutputError> {
    let OutputTarget::File(file) = resolve_output(output, flag)? else {
        return Ok(());
    };
    let dir = parent_dir(&file);
    if !dir.is_dir() {
        return Err(refused(
            flag,
            output,
            format!(
                "a file in an existing folder ({} does not exist)",
                dir.display()
            ),
        ));
    }
    check_can_create(dir, flag, output, "a file in a folder this user can write")
}

/// Refuses `output` (option `flag`) unless a file can be created in the folder `dir`: a trial
/// temporary, listed for removal on a signal, is created there and removed at once. `expected` says
/// what is accepted.
pub(crate) fn check_can_create(
    dir: &Path,
    flag: &str,
    output: &Path,
    expected: &str,
) -> Result<(), OutputError> {
    let mut builder = tempfile::Builder::new();
    builder.prefix(TEMP_PREFIX).suffix(".tmp");
    match cleanup::Pending::create(&builder, dir) {
        Ok((tmp, pending)) => {
            drop(tmp);
            drop(pending);
            Ok(())
        }
        Err(e) => Err(refused(
            flag,
            output,
            format!(
                "{expected} (no file can be created in {}: {}; checked before the run)",
                dir.display(),
                without_temp_path(e)
            ),
        )),
    }
}

/// `e` without the path of the hidden temporary file that `tempfile` appends to its errors
/// (`… at path "/x/.ipa-sysid-Av9FNE.tmp"`): the message names the user's output instead.
fn without_temp_path(e: std::io::Error) -> std::io::Error {
    let text = e.to_string();
    match text.find(" at path \"") {
        Some(at) if text[at..].contains(TEMP_PREFIX) => {
            std::io::Error::new(e.kind(), text[..at].to_string())
        }
        _ => e,
    }
}

/// Whether standard output is a pipe or socket whose reader has gone (`ipa-sysid … | head` after
/// `head` ended): `poll` reports an error or hang-up on it. The command line then ends quietly with
/// exit 0 (a reader that stopped early is not an error, audit s36 L-2). False where unknown.
#[cfg(unix)]
pub fn stdout_reader_gone() -> bool {
    let mut fd = libc::pollfd {
        fd: libc::STDOUT_FILENO,
        events: 0,
        revents: 0,
    };
    // SAFETY: one pollfd that lives across the call; a zero time-out does not block.
    let r = unsafe { libc::poll(&mut fd, 1, 0) };
    r == 1 && fd.revents & (libc::POLLERR | libc::POLLHUP) != 0
}

/// Not known off Unix.
#[cfg(not(unix))]
pub fn stdout_reader_gone() -> bool {
    false
}

/// The folder that holds `path` (`.` for a bare file name).
pub(crate) fn parent_dir(path: &Path) -> &Path {
    match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    }
}

/// The file that marks a folder as written by `reproduce` ([`write_claimed_folder`]).
pub const FOLDER_MARKER: &str = ".ipa-sysid-output";

/// Writes the folder `dir` (chosen by option `flag`) of a run of `tool` as a whole ([`write_folder`]:
/// `fill` writes into a temporary folder beside `dir`, renamed into place at the end; when `fill` fails
/// or a signal stops the process, the temporary folder is removed and `dir` is as it was). An existing
/// folder is accepted when it is empty or holds the marker [`FOLDER_MARKER`] (written by a previous
/// run); any other folder is refused before `fill` runs, naming what it holds, so that a user's own
/// files are never replaced. The new folder holds the marker; the files of a marked folder that the
/// new run did not write (a note the user added, a figure of an older version) are copied into it, so
/// replacing the folder loses nothing the run would not have replaced file by file. Returns whether an
/// existing folder with entries was replaced ([`write_folder`]).
pub fn write_claimed_folder<E>(
    dir: &Path,
    flag: &str,
    tool: &str,
    fill: impl FnOnce(&Path) -> Result<(), E>,
) -> Result<bool, E>
where
    E: From<OutputError>,
{
    folder::check_folder_path(dir, flag)?;
    check_claim(dir, flag, tool)?;
    refuse_special_entries(dir, flag)?;
    write_folder(dir, flag, true, |tmp: &Path| {
        write_atomic(
            &tmp.join(FOLDER_MARKER),
            format!(
                "This folder was written by `{tool}`; the next run into it replaces its files.\n"
            )
            .as_bytes(),
        )?;
        fill(tmp)?;
        if dir.is_dir() {
            copy_missing(dir, tmp).map_err(|source| OutputError::Io {
                path: dir.to_path_buf(),
                source,
            })?;
        }
        Ok(())
    })
}

/// Copies every entry of `from` that `to` lacks (recursively into folders both hold); links are not
/// followed.
fn copy_missing(from: &Path, to: &Path) -> std::io::Result<()> {
    for e in std::fs::read_dir(from)? {
        let e = e?;
        let (src, dst) = (e.path(), to.join(e.file_name()));
        let kind = e.file_type()?;
        match std::fs::symlink_metadata(&dst) {
            Ok(m) if m.is_dir() && kind.is_dir() => copy_missing(&src, &dst)?,
            Ok(_) => {}
            Err(_) if kind.is_dir() => {
                std::fs::create_dir(&dst)?;
                copy_missing(&src, &dst)?;
            }
            Err(_) if kind.is_file() => {
                std::fs::copy(&src, &dst)?;
            }
            #[cfg(unix)]
            Err(_) if kind.is_symlink() => {
                std::os::unix::fs::symlink(std::fs::read_link(&src)?, &dst)?;
            }
            Err(_) => {}
        }
    }
    Ok(())
}

/// Refuses a folder `dir` (option `flag`) of an earlier run that holds, at any depth, an entry that
/// [`copy_missing`] cannot carry into the new folder — a FIFO, a socket, a device — before the run:
/// replacing the folder would delete it (audit s36 L-8: a user's named pipe and socket vanished). Links
/// are not followed.
fn refuse_special_entries(dir: &Path, flag: &str) -> Result<(), OutputError> {
    fn find(d: &Path) -> std::io::Result<Option<(PathBuf, std::fs::FileType)>> {
        for e in std::fs::read_dir(d)? {
            let e = e?;
            let kind = e.file_type()?;
            if kind.is_dir() {
                if let Some(found) = find(&e.path())? {
                    return Ok(Some(found));
                }
            } else if !kind.is_file() && !kind.is_symlink() {
                return Ok(Some((e.path(), kind)));
            }
        }
        Ok(None)
    }
    if !std::fs::symlink_metadata(dir).is_ok_and(|m| m.is_dir()) {
        return Ok(());
    }
    match find(dir) {
        Ok(None) => Ok(()),
        Ok(Some((entry, kind))) => Err(refused(
            flag,
            dir,
            format!(
                "a folder whose entries are files, folders and links ({} is {}, which the new \
                 folder cannot take over: replacing the folder would delete it; move it out of the \
                 folder first)",
                entry.display(),
                folder::special_kind(&kind)
            ),
        )),
        Err(source) => Err(OutputError::Io {
            path: dir.to_path_buf(),
            source,
        }),
    }
}

/// Refuses `dir` unless it is missing, empty or holds [`FOLDER_MARKER`] ([`write_claimed_folder`]).
fn check_claim(dir: &Path, flag: &str, tool: &str) -> Result<(), OutputError> {
    let io = |source| OutputError::Io {
        path: dir.to_path_buf(),
        source,
    };
    match std::fs::read_dir(dir) {
        Ok(entries) => {
            let mut names: Vec<String> = Vec::new();
            let mut count = 0usize;
            for e in entries {
                let e = e.map_err(io)?;
                if e.file_name() == FOLDER_MARKER {
                    return Ok(());
                }
                count += 1;
                if names.len() < 5 {
                    names.push(e.file_name().to_string_lossy().into_owned());
                }
            }
            if count > 0 {
                names.sort();
                return Err(refused(
                    flag,
                    dir,
                    format!(
                        "a new or empty folder, or one written by a previous `{tool}` (holding {FOLDER_MARKER}); \
                         this one holds {count} other entr{} ({}{}) that the run could replace",
                        if count == 1 { "y" } else { "ies" },
                        names.join(", "),
                        if count > names.len() { ", ..." } else { "" }
                    ),
                ));
            }
            Ok(())
        }
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(()),
        Err(e) => Err(io(e)),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod folder_tests {
    use super::*;

    fn fill(files: &'static [&'static str]) -> impl FnOnce(&Path) -> Result<(), OutputError> {
        move |d: &Path| {
            for f in files {
                std::fs::write(d.join(f), "new").unwrap();
            }
            Ok(())
        }
    }

    // A missing folder is written whole and marked; a marked folder is replaced, keeping the files the
    // new run did not write; a folder of other files is refused and left as it was; a failed fill
    // leaves the folder as it was and no temporary folder.
    #[test]
    fn only_new_empty_or_marked_folders_are_written() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("out");
        write_claimed_folder(&out, "--out", "test", fill(&["report.html"])).unwrap();
        assert!(out.join(FOLDER_MARKER).is_file());
        std::fs::write(out.join("notes.txt"), "mine").unwrap();
        write_claimed_folder(&out, "--out", "test", fill(&["report.html", "b.json"])).unwrap();
        assert_eq!(
            std::fs::read_to_string(out.join("notes.txt")).unwrap(),
            "mine"
        );
        assert!(out.join("b.json").is_file());
        let e = write_claimed_folder(&out, "--out", "test", |d: &Path| {
            std::fs::write(d.join("report.html"), "half").unwrap();
            Err(OutputError::Io {
                path: d.to_path_buf(),
                source: std::io::Error::other("failed"),
            })
        });
        assert!(e.is_err());
        assert_eq!(
            std::fs::read_to_string(out.join("report.html")).unwrap(),
            "new"
        );
        let theirs = dir.path().join("theirs");
        std::fs::create_dir(&theirs).unwrap();
        std::fs::write(theirs.join("report.html"), "mine").unwrap();
        let e = write_claimed_folder(&theirs, "--out", "test", fill(&["report.html"]))
            .unwrap_err()
            .to_string();
        assert!(e.contains("report.html"), "{e}");
        assert!(!theirs.join(FOLDER_MARKER).exists());
        assert_eq!(
            std::fs::read_to_string(theirs.join("report.html")).unwrap(),
            "mine"
        );
        let empty = dir.path().join("empty");
        std::fs::create_dir(&empty).unwrap();
        write_claimed_folder(&empty, "--out", "test", fill(&["a"])).unwrap();
        let left: Vec<_> = std::fs::read_dir(dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| n.starts_with(TEMP_PREFIX))
            .collect();
        assert!(left.is_empty(), "{left:?}");
    }
}

#[cfg(all(test, unix))]
#[allow(clippy::unwrap_used)]
mod special_entry_tests {
    use super::*;

    // A folder of an earlier run holding a FIFO (at any depth) or a socket is refused before the run,
    // naming the entry, and the entry stays (audit s36 L-8: replacing the folder deleted them); the
    // same folder without them is written.
    #[test]
    fn fifos_and_sockets_in_an_earlier_runs_folder_are_refused_before_the_run() {
        let root = tempfile::tempdir().unwrap();
        let out = root.path().join("out");
        let fill = |d: &Path| -> Result<(), OutputError> {
            std::fs::write(d.join("report.html"), "new").unwrap();
            Ok(())
        };
        write_claimed_folder(&out, "--out", "test", fill).unwrap();
        std::fs::create_dir(out.join("mine")).unwrap();
        let fifo = out.join("mine/pipe");
        let c = std::ffi::CString::new(fifo.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: a NUL-terminated path that outlives the call.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
        let ran = std::cell::Cell::new(false);
        let e = write_claimed_folder(&out, "--out", "test", |d: &Path| {
            ran.set(true);
            fill(d)
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("mine/pipe") && e.contains("FIFO"), "{e}");
        assert!(!ran.get(), "refused before the run");
        assert!(is_fifo(&fifo));
        std::fs::remove_file(&fifo).unwrap();
        let sock = out.join("sock");
        let _listener = std::os::unix::net::UnixListener::bind(&sock).unwrap();
        let e = write_claimed_folder(&out, "--out", "test", fill)
            .unwrap_err()
            .to_string();
        assert!(e.contains("sock") && e.contains("a socket"), "{e}");
        assert!(std::fs::symlink_metadata(&sock).is_ok());
        std::fs::remove_file(&sock).unwrap();
        write_claimed_folder(&out, "--out", "test", fill).unwrap();
        assert!(out.join("mine").is_dir());
    }

    // A folder where no file can be created (/proc/self, even for root) is refused by the check before
    // the run, in words naming the folder and not the hidden trial temporary (audit s36 L-1).
    #[cfg(target_os = "linux")]
    #[test]
    fn an_output_in_a_folder_nobody_can_write_is_refused_before_the_run() {
        let out = Path::new("/proc/self/out.json");
        if !Path::new("/proc/self").is_dir() {
            eprintln!("SKIPPED: no /proc on this machine");
            return;
        }
        let e = check_writable(out, "--json").unwrap_err().to_string();
        assert!(e.contains("--json") && e.contains("/proc/self"), "{e}");
        assert!(e.contains("no file can be created"), "{e}");
        assert!(!e.contains(TEMP_PREFIX), "{e}");
    }
}

#[cfg(all(test, unix))]
#[allow(clippy::unwrap_used)]
mod device_tests {
    use super::*;
    use std::os::unix::fs::FileTypeExt;

    // Only looks at the paths (resolve_output_as writes nothing): a block device is never an output,
    // another character device only with --force, /dev/null always (audit s24 H-1).
    #[test]
    fn block_devices_are_never_outputs_and_other_character_devices_need_force() {
        let null = Path::new("/dev/null");
        for force in [false, true] {
            assert_eq!(
                resolve_output_as(null, "--out", force).unwrap(),
                OutputTarget::Stream(null.to_path_buf())
            );
        }
        let urandom = Path::new("/dev/urandom");
        let err = resolve_output_as(urandom, "--out", false)
            .unwrap_err()
            .to_string();
        assert!(err.contains("character device that is neither"), "{err}");
        assert!(err.contains("--force"), "{err}");
        assert_eq!(
            resolve_output_as(urandom, "--out", true).unwrap(),
            OutputTarget::Stream(urandom.to_path_buf())
        );
        let block = std::fs::read_dir("/dev").ok().and_then(|d| {
            d.flatten()
                .map(|e| e.path())
                .find(|p| std::fs::metadata(p).is_ok_and(|m| m.file_type().is_block_device()))
        });
        let Some(block) = block else {
            eprintln!("SKIPPED the block-device half: no block device in /dev on this machine");
            return;
        };
        for force in [false, true] {
            let err = resolve_output_as(&block, "--out", force)
                .unwrap_err()
                .to_string();
            assert!(err.contains("block device"), "{}: {err}", block.display());
        }
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod kind_tests {
    use super::*;

    // Kinds read from hand-written file beginnings: the first key "format" names a model or controller
    // file; other JSON is a report; a text file is known by its first line (a CSV's header row).
    #[test]
    fn file_kinds_are_read_from_the_first_bytes() {
        let model = FileKind::of(b"{\n  \"format\": \"ipa-sysid-model\",\n  \"version\": 3\n}");
        assert_eq!(model, FileKind::Format("ipa-sysid-model".into()));
        assert_eq!(
            FileKind::of(b"\xEF\xBB\xBF {\"format\":\"ipa-sysid-controller\"}"),
            FileKind::Format("ipa-sysid-controller".into())
        );
        assert_eq!(
            FileKind::of(b"{\"model\": {\"format\": \"x\"}}"),
            FileKind::Json
        );
        // The core's one rule (sysid_core::data::json_format_key): a top-level "format" after other
        // keys counts (the writer's old rule took the first key only), one in a string value does not.
        assert_eq!(
            FileKind::of(b"{\"version\": 3, \"format\": \"ipa-sysid-model\"}"),
            FileKind::Format("ipa-sysid-model".into())
        );
        assert_eq!(
            FileKind::of(b"{\"title\": \"\\\"format\\\": \\\"x\\\"\"}"),
            FileKind::Json
        );
        assert_eq!(
            FileKind::of(b"t,u,y\r\n0,1,2\n"),
            FileKind::Text("t,u,y".into())
        );
        assert_eq!(FileKind::of(b" \n\t"), FileKind::Empty);
        assert_eq!(FileKind::of(b"\x89PNG\r\n\x1a\n...."), FileKind::Png);
        assert_eq!(FileKind::of(b"PAR1...."), FileKind::Parquet);
        assert_eq!(FileKind::of(b"<!DOCTYPE html><html>"), FileKind::OtherHtml);
        assert_eq!(
            FileKind::of(b"<!DOCTYPE html>\n<html><head><meta name=\"generator\" content=\"ipa-sysid 0.1.0\" />"),
            FileKind::Html
        );
        assert_eq!(FileKind::of(b"<svg xmlns="), FileKind::Svg);
        assert_eq!(FileKind::of(b"a\0b"), FileKind::Binary);
        assert_eq!(
            FileKind::of(b"# Digital twin calibrated by `ipa-sysid calibrate` on a.csv\n[x]\n"),
            FileKind::PlantToml
        );
        let csv = FileKind::Text("t,u,y".into());
        assert!(csv.may_replace(&FileKind::Text("t,u,y".into())));
        assert!(!csv.may_replace(&FileKind::Text("time,force".into())));
        assert!(!csv.may_replace(&model));
        assert!(csv.may_replace(&FileKind::Empty));
        assert!(!FileKind::Format("ipa-sysid-controller".into()).may_replace(&model));
        assert_eq!(model.describe(), "an ipa-sysid-model file (JSON)");
        assert_eq!(csv.describe(), "a CSV table with header t,u,y");
        assert_eq!(
            FileKind::Text("\u{1b}[2J".into()).describe(),
            "text beginning \"\\u{1b}[2J\""
        );
    }

    // A file is known by its first KIND_HEAD bytes only: a "format" key past them is not seen (the file
    // is not read whole), one within them is, wherever it stands among the top-level keys.
    #[test]
    fn a_file_kind_is_read_from_a_bounded_head() {
        let dir = tempfile::tempdir().unwrap();
        let pad = "x".repeat(KIND_HEAD);
        let late = dir.path().join("late.json");
        std::fs::write(
            &late,
            format!("{{\"pad\": \"{pad}\", \"format\": \"ipa-sysid-model\"}}"),
        )
        .unwrap();
        assert_eq!(FileKind::of_file(&late).unwrap(), FileKind::Json);
        let early = dir.path().join("early.json");
        std::fs::write(
            &early,
            format!("{{\"v\": 1, \"format\": \"ipa-sysid-model\", \"pad\": \"{pad}\"}}"),
        )
        .unwrap();
        assert_eq!(
            FileKind::of_file(&early).unwrap(),
            FileKind::Format("ipa-sysid-model".into())
        );
    }

    // Without force, a file of another kind is refused and kept; the same kind is replaced and
    // reported; a symbolic link to a file is refused; with force both are written.
    #[test]
    fn only_the_same_kind_is_replaced_without_force() {
        let dir = tempfile::tempdir().unwrap();
        let model = dir.path().join("model.json");
        std::fs::write(&model, "{\"format\": \"ipa-sysid-model\"}").unwrap();
        let e = write_all_atomic_as(&[(&model, b"t,u,y\n0,0,0\n")], false).unwrap_err();
        assert!(matches!(e, OutputError::Occupied { .. }), "{e}");
        assert!(e.to_string().contains("--force"), "{e}");
        assert_eq!(
            std::fs::read_to_string(&model).unwrap(),
            "{\"format\": \"ipa-sysid-model\"}"
        );
        let new = dir.path().join("new.csv");
        let replaced = write_all_atomic_as(
            &[
                (&new, b"t,u,y\n1,1,1\n"),
                (&model, b"{\"format\": \"ipa-sysid-model\", \"v\": 2}"),
            ],
            false,
        )
        .unwrap();
        assert_eq!(replaced, vec![model.clone()]);
        // Nothing is written when one output of several is refused.
        let e = write_all_atomic_as(&[(&new, b"t,u,y\n2,2,2\n"), (&model, b"x,y\n")], false);
        assert!(e.is_err());
        assert_eq!(std::fs::read_to_string(&new).unwrap(), "t,u,y\n1,1,1\n");
        #[cfg(unix)]
        {
            let link = dir.path().join("link.csv");
            std::os::unix::fs::symlink(&new, &link).unwrap();
            assert!(resolve_output_as(&link, "--out", false).is_err());
            assert!(write_all_atomic_as(&[(&link, b"t,u,y\n3,3,3\n")], false).is_err());
            assert_eq!(
                write_all_atomic_as(&[(&link, b"t,u,y\n3,3,3\n")], true).unwrap(),
                vec![link.clone()]
            );
            assert_eq!(std::fs::read_to_string(&new).unwrap(), "t,u,y\n3,3,3\n");
            assert_eq!(
                write_all_atomic_as(&[(Path::new("/dev/null"), b"x")], false).unwrap(),
                Vec::<PathBuf>::new()
            );
        }
        write_all_atomic_as(&[(&model, b"a,b\n")], true).unwrap();
        assert_eq!(std::fs::read_to_string(&model).unwrap(), "a,b\n");
    }
}

#[cfg(all(test, target_os = "linux"))]
#[allow(clippy::unwrap_used)]
mod mark_tests {
    use super::*;

    /// Whether the file system of `dir` keeps user extended attributes (set by hand with libc, not
    /// through the code under test).
    fn keeps_user_attributes(dir: &Path) -> bool {
        use std::os::unix::ffi::OsStrExt;
        let probe = dir.join("probe");
        std::fs::write(&probe, "x").unwrap();
        let p = std::ffi::CString::new(probe.as_os_str().as_bytes()).unwrap();
        let name = std::ffi::CString::new("user.probe").unwrap();
        // SAFETY: NUL-terminated strings and a one-byte value that live across the call.
        let r = unsafe { libc::setxattr(p.as_ptr(), name.as_ptr(), b"1".as_ptr().cast(), 1, 0) };
        std::fs::remove_file(&probe).unwrap();
        r == 0
    }

    // A measured record whose header row is exactly an output's (`control --out`'s t,r,u,y) is kept
    // without --force; an output of ipa-sysid with that header is replaced; with force both are.
    #[test]
    fn a_record_with_an_outputs_header_is_not_taken_for_an_output() {
        let dir = tempfile::tempdir().unwrap();
        if !keeps_user_attributes(dir.path()) {
            eprintln!(
                "SKIPPED: {} keeps no user extended attributes (the rule falls back to the kind)",
                dir.path().display()
            );
            return;
        }
        let record = dir.path().join("log.csv");
        std::fs::write(&record, "t,r,u,y\n0,50,0,49.9\n").unwrap();
        assert_eq!(output_mark(&record), Mark::Unmarked);
        let e = write_all_atomic_as(&[(&record, b"t,r,u,y\n0,1,2,3\n")], false).unwrap_err();
        assert!(matches!(e, OutputError::Occupied { .. }), "{e}");
        let text = e.to_string();
        assert!(
            text.contains("did not write") && text.contains(OUTPUT_MARK),
            "{text}"
        );
        assert_eq!(
            std::fs::read_to_string(&record).unwrap(),
            "t,r,u,y\n0,50,0,49.9\n"
        );
        // A picture of the user's is kept as well.
        let png = dir.path().join("photo.png");
        std::fs::write(&png, b"\x89PNG\r\n\x1a\nuser").unwrap();
        assert!(write_all_atomic_as(&[(&png, b"\x89PNG\r\n\x1a\nours")], false).is_err());
        // An output of ipa-sysid carries the mark and is replaced by the next run's.
        let out = dir.path().join("out.csv");
        write_atomic(&out, b"t,r,u,y\n0,1,2,3\n").unwrap();
        assert_eq!(output_mark(&out), Mark::Marked);
        assert_eq!(
            write_all_atomic_as(&[(&out, b"t,r,u,y\n4,5,6,7\n")], false).unwrap(),
            vec![out.clone()]
        );
        assert_eq!(output_mark(&out), Mark::Marked);
        // A copy without its attributes (`cp` without --preserve) is a user's file again.
        let copy = dir.path().join("copy.csv");
        std::fs::write(&copy, std::fs::read(&out).unwrap()).unwrap();
        assert!(write_all_atomic_as(&[(&copy, b"t,r,u,y\n8,8,8,8\n")], false).is_err());
        // --force replaces the record.
        write_all_atomic_as(&[(&record, b"t,r,u,y\n9,9,9,9\n")], true).unwrap();
        assert_eq!(
            std::fs::read_to_string(&record).unwrap(),
            "t,r,u,y\n9,9,9,9\n"
        );
    }
}

#[cfg(all(test, unix))]
#[allow(clippy::unwrap_used)]
mod fifo_tests {
    use super::*;
    use std::io::Read;

    fn make_fifo(path: &Path) {
        let c = std::ffi::CString::new(path.as_os_str().as_encoded_bytes()).unwrap();
        // SAFETY: `c` is a NUL-terminated path that outlives the call.
        assert_eq!(unsafe { libc::mkfifo(c.as_ptr(), 0o600) }, 0);
    }

    fn fifo_kind(path: &Path) -> bool {
        use std::os::unix::fs::FileTypeExt;
        std::fs::symlink_metadata(path)
            .unwrap()
            .file_type()
            .is_fifo()
    }

    // A FIFO nobody opens: the wait asks `keep_waiting` until it says stop; its error is the result,
    // nothing is left beside the FIFO, and the FIFO stays a FIFO.
    #[test]
    fn a_fifo_without_reader_waits_only_while_keep_waiting_agrees() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        make_fifo(&fifo);
        let mut calls = 0;
        let mut stop_at_three = || {
            calls += 1;
            if calls < 3 {
                Ok(())
            } else {
                Err(std::io::Error::other("stop"))
            }
        };
        let e = write_all_atomic_waiting(&[(&fifo, b"x")], false, Some(&mut stop_at_three))
            .unwrap_err();
        assert!(
            matches!(&e, OutputError::Io { path, source } if path == &fifo && source.to_string() == "stop"),
            "{e:?}"
        );
        assert_eq!(calls, 3);
        assert!(fifo_kind(&fifo));
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    // More than a pipe holds (64 KiB on Linux), read by a slow reader: every byte arrives in order, the
    // full pipe asking `keep_waiting` in between; a regular file beside it in the same call is written.
    #[test]
    fn a_fifo_with_a_slow_reader_gets_every_byte() {
        let dir = tempfile::tempdir().unwrap();
        let fifo = dir.path().join("pipe");
        make_fifo(&fifo);
        let file = dir.path().join("out.csv");
        let data: Vec<u8> = (0..300_000u32).map(|i| (i % 251) as u8).collect();
        let reader = {
            let fifo = fifo.clone();
            std::thread::spawn(move || {
                std::thread::sleep(std::time::Duration::from_millis(50));
                let mut f = std::fs::File::open(&fifo).unwrap();
                let (mut got, mut buf) = (Vec::new(), [0u8; 8192]);
                loop {
                    let k = f.read(&mut buf).unwrap();
                    if k == 0 {
                        return got;
                    }
                    got.extend_from_slice(&buf[..k]);
                    std::thread::sleep(std::time::Duration::from_millis(1));
                }
            })
        };
        let mut waits = 0;
        let mut count = || {
            waits += 1;
            Ok(())
        };
        write_all_atomic_waiting(
            &[(&fifo, &data), (&file, b"t,u,y\n0,0,0\n")],
            false,
            Some(&mut count),
        )
        .unwrap();
        assert_eq!(reader.join().unwrap(), data);
        assert!(
            waits > 0,
            "the reader opened late and the pipe filled: the wait was asked"
        );
        assert_eq!(std::fs::read(&file).unwrap(), b"t,u,y\n0,0,0\n");
        assert!(fifo_kind(&fifo));
    }
}
