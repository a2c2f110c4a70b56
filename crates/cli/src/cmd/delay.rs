//! `ipa-sysid delay`: estimate the input delay nk (MATLAB `delayest`); the logic is
//! `sysid::delay::estimate_delay`.

use std::path::{Path, PathBuf};

use super::common::{check_outputs, print_notes, print_report, write_outputs, ColumnArgs};

/// Flags of `delay`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// CSV file with the record (columns chosen by --u-col, --y-col, --t-col).
    #[arg(long, value_name = "FILE")]
    pub data: PathBuf,
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Largest delay to try, in samples (delays 0..=N are compared).
    #[arg(long, default_value_t = 10, value_name = "N")]
    pub max_delay: usize,
    /// na of the ARX models compared (MATLAB `delayest` default 2).
    #[arg(long, default_value_t = 2)]
    pub na: usize,
    /// nb of the ARX models compared (MATLAB `delayest` default 2).
    #[arg(long, default_value_t = 2)]
    pub nb: usize,
    /// Write the result as JSON here (`-` for standard output); its `nk` is the estimate.
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Exit with code 1 when the result carries warnings (they are printed either way), without writing
    /// --json (an earlier file there is kept).
    #[arg(long)]
    pub strict: bool,
    #[command(flatten)]
    pub memory: super::common::MemoryArgs,
}

/// Runs `delay`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let inputs: [&Path; 1] = [&args.data];
    check_outputs(&[(&args.json, "--json")], &inputs)?;
    let record = sysid::data::read_record(&args.data, &args.columns.csv_options(&args.memory))?;
    print_notes(&record.notes);
    let data = record.data;
    // A long search (seconds to minutes on tens of millions of samples) says on stderr how far it
    // is, one line per delay fitted, instead of running silently (audit s19 H-1).
    let candidates = args.max_delay.saturating_add(1);
    let long = data.len().saturating_mul(candidates) >= sysid::delay::PROGRESS_WORK;
    let est = sysid::delay::estimate_delay_with_progress(
        &data,
        args.na,
        args.nb,
        args.max_delay,
        &|c: &sysid::delay::DelayCandidate| {
            if long {
                eprintln!(
                    "delay: nk = {} fitted ({} of {candidates}, {} samples)",
                    c.nk,
                    c.nk + 1,
                    data.len()
                );
            }
        },
        args.memory.max_memory,
    )?;
    let mut text = format!(
        "Delay estimate on {} ({} samples): nk = {} samples ({} s{}), from ARX(na = {}, nb = {}, nk) fits \
         with a constant term on the same {} rows\n\n{:>4} {:>14} {:>24}\n",
        data.name(),
        data.len(),
        est.nk,
        report::format::num(est.nk as f64 * data.ts()),
        if est.blocked() {
            "; not determined: nk + 1 could not be fitted, see the warning"
        } else {
            ""
        },
        est.na,
        est.nb,
        est.n,
        "nk",
        "loss V",
        "b(nk) ± std"
    );
    for c in &est.candidates {
        // The coefficient of u(k − nk), the candidate's first input lag: the delay is the first lag whose
        // coefficient is clear of noise (sysid::delay).
        let lead = match (c.b_lead, c.b_lead_std) {
            (Some(b), Some(s)) => {
                format!("{} ± {}", report::format::num(b), report::format::num(s))
            }
            (Some(b), None) => format!("{} ± n/a", report::format::num(b)),
            _ => "n/a".to_string(),
        };
        text.push_str(&format!(
            "{:>4} {:>14} {:>24}{}\n",
            c.nk,
            c.loss
                .map_or_else(|| "n/a".to_string(), report::format::num),
            lead,
            match (&c.error, c.nk == est.nk) {
                (_, true) => "  <- best".to_string(),
                (Some(e), false) => format!("  ({e})"),
                (None, false) => String::new(),
            }
        ));
    }
    if !est.warnings.is_empty() || !est.notes.is_empty() {
        text.push('\n');
    }
    for n in &est.notes {
        text.push_str(&format!("note: {n}\n"));
    }
    for w in &est.warnings {
        text.push_str(&format!("warning: {w}\n"));
    }
    print_report(&text, &[args.json.as_deref()])?;
    // The reader's notes are printed as warnings too (`print_notes`) and counted by --strict.
    let warnings: Vec<&String> = est.warnings.iter().chain(&record.notes).collect();
    let json = match &args.json {
        Some(_) => Some(
            super::common::report_json(
                &serde_json::json!({
                    "data": data.name(),
                    "ts": data.ts(),
                    "nk": est.nk,
                    "delay_s": est.nk as f64 * data.ts(),
                    "na": est.na,
                    "nb": est.nb,
                    "n": est.n,
                    "margin": est.margin,
                    "candidates": est.candidates,
                    "notes": est.notes,
                    "warnings": warnings,
                }),
                true,
            )? + "\n",
        ),
        None => None,
    };
    let mut outputs: Vec<(&Path, &[u8], &str)> = Vec::new();
    if let (Some(path), Some(text)) = (&args.json, &json) {
        outputs.push((path, text.as_bytes(), "--json"));
    }
    // With --strict and warnings, --json is not written (an earlier file stays) and the exit code is 1.
    write_outputs(&outputs, &inputs, args.strict, warnings.len())
}
