//! Writing output files safely: atomically (temporary file in the same folder, then rename), never over
//! one of the run's input files.

use std::io::Write;
use std::path::Path;

use crate::SysidError;

/// Writes `bytes` to `path` atomically: the content goes to a temporary file beside `path`, which is
/// then renamed over it, so a crash never leaves a half-written file.
pub fn write_atomic(path: &Path, bytes: &[u8]) -> Result<(), SysidError> {
    let io = |source| SysidError::Io { path: path.to_path_buf(), source };
    let dir = match path.parent() {
        Some(p) if !p.as_os_str().is_empty() => p,
        _ => Path::new("."),
    };
    let mut tmp = tempfile::Builder::new().prefix(".ipa-sysid-").suffix(".tmp").tempfile_in(dir).map_err(io)?;
    tmp.write_all(bytes).map_err(io)?;
    tmp.as_file().sync_all().map_err(io)?;
    tmp.persist(path).map_err(|e| io(e.error))?;
    Ok(())
}

/// Refuses to write `output` when it is the same file as any of `inputs` (compared after resolving
/// links, so `./a.csv` and `a.csv` are the same file).
pub fn refuse_overwrite_input(output: &Path, inputs: &[&Path], flag: &str) -> Result<(), SysidError> {
    let canon = |p: &Path| std::fs::canonicalize(p).ok();
    if let Some(out) = canon(output) {
        for input in inputs {
            if canon(input).as_deref() == Some(out.as_path()) {
                return Err(SysidError::setting(
                    flag,
                    output.display(),
                    "an output path different from every input file (refusing to overwrite your data)",
                ));
            }
        }
    }
    Ok(())
}
