//! `ipa-sysid identify --structure narx`: a polynomial NARX model, its terms chosen by orthogonal
//! forward regression (FROLS) with an honest stopping rule (`sysid::narx`).

use sysid::narx::{identify_narx, NarxSettings, StopRule};
use sysid_summary::narx::NarxReport;

use super::common::print_report;
use super::identify::Args;
use std::path::Path;

/// The flags of [`NarxArgs`], (argument id, flag): `identify` refuses them without `--structure
/// narx`, `order` without a narxD class (a flag typed is known by its id).
pub const NARX_FLAGS: [(&str, &str); 4] = [
    ("stop", "--stop"),
    ("max_terms", "--max-terms"),
    ("selection", "--selection"),
    ("no_refine", "--no-refine"),
];

/// Flags that only polynomial NARX models use.
#[derive(Debug, Clone, clap::Args)]
pub struct NarxArgs {
    /// Polynomial NARX: how many FROLS-ordered terms to keep: `sim` (default) the least free-run
    /// simulation RMSE on the selection part (the last --selection fraction of the estimation record,
    /// terms ordered on the rest), `aic` or `bic` on the one-step residuals of the estimation record.
    #[arg(long, value_enum, default_value = "sim")]
    pub stop: StopRule,
    /// Polynomial NARX: at most this many terms are ordered by FROLS.
    #[arg(long, value_name = "N", default_value_t = 30)]
    pub max_terms: usize,
    /// Polynomial NARX with --stop sim: the fraction of the estimation record (its end) that chooses
    /// the number of terms.
    #[arg(long, value_name = "F", default_value_t = 1.0 / 3.0)]
    pub selection: f64,
    /// Polynomial NARX: keep the least-squares (one-step) coefficients; by default they are refined on
    /// the free-run simulation error of the estimation record (Levenberg–Marquardt).
    #[arg(long)]
    pub no_refine: bool,
}

impl NarxArgs {
    /// The NARX settings of these flags with the lags of `identify` (`--offset` offers the constant).
    ///
    /// `degree` is `identify --degree` (the NARX default 2 when absent); `order --classes` names it in
    /// each class.
    pub fn settings(
        &self,
        (na, nb, nk): (usize, usize, usize),
        degree: usize,
        offset: bool,
        max_iterations: usize,
        max_memory: sysid::ls::MemoryBudget,
    ) -> NarxSettings {
        NarxSettings {
            na,
            nb,
            nk,
            degree,
            constant: offset,
            max_terms: self.max_terms,
            stop: self.stop,
            selection: self.selection,
            refine: !self.no_refine,
            max_iterations,
            max_memory,
            // The command line's SIGINT ends the process.
            cancel: sysid::Stop::never(),
        }
    }
}

/// Runs `identify --structure narx`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    if args.columns.u_col.contains(',') || args.merge || args.data.len() > 1 {
        anyhow::bail!(
            "--structure narx identifies one record with one input (no --merge, no input list, one --data file)"
        );
    }
    if args.detrend != sysid::detrend::Detrend::None {
        anyhow::bail!(
            "--structure narx takes no --detrend: offer the constant term with --offset instead"
        );
    }
    if args.nb.0.len() > 1 || args.nk.0.len() > 1 {
        anyhow::bail!("--nb/--nk lists are for several inputs; --structure narx has one");
    }
    if args.nonlinearity.is_some() || args.output_nonlinearity.is_some() {
        anyhow::bail!(
            "--structure narx has no static blocks: its polynomial terms are the nonlinearity \
             (leave out --nonlinearity and --output-nonlinearity)"
        );
    }
    let settings = args.narx.settings(
        (args.na, args.nb.first(), args.nk.first()),
        args.degree.unwrap_or(2),
        args.offset,
        args.max_iterations.min(200),
        args.memory.max_memory,
    );
    settings.check()?;
    let data_path = &args.data[0];
    let inputs = super::identify::checked_inputs(args, data_path)?;
    let records = args
        .val
        .records(data_path, &args.columns.csv_options(&args.memory))?;
    let fit = identify_narx(&records.est, &settings)?;
    let mut report = NarxReport::assemble(fit, &settings, &records.est, records.val.as_ref())?;
    report
        .warnings
        .extend(super::common::data_notes(&records.notes));
    // A validation record that is the estimation data (the same rows, or a copy) is in-sample: said as
    // for every other structure (audit s12 F2).
    report.warnings.extend(super::identify::in_sample_warnings(
        args,
        &args.data,
        std::slice::from_ref(&records.est),
        records.val.as_ref(),
    ));
    report.warnings.extend(offset_hint(&records.est, &settings));
    print_report(
        &render(&report, &settings),
        &[args.json.as_deref(), args.save_model.as_deref()],
    )?;
    let json = match &args.json {
        Some(_) => Some(super::common::report_json(&report, true)? + "\n"),
        None => None,
    };
    // The model file records its identification, as a linear model's does: validate compares its fit
    // with the estimation fit and repeats the warnings (audit s33 M-1). The fit is the free run's
    // (from the measured initial outputs: a NARX model's only simulation).
    let saved = match &args.save_model {
        Some(_) => {
            let provenance = super::identify::provenance(
                args,
                records.est.name(),
                report.metrics.estimation.fit_sim_percent,
                &report.warnings,
            );
            Some(sysid::model_file::narx_to_json(
                &report.model.clone().with_provenance(Some(provenance))?,
            )?)
        }
        None => None,
    };
    let mut outputs: Vec<(&Path, &[u8], &str)> = Vec::new();
    if let (Some(path), Some(text)) = (&args.json, &json) {
        outputs.push((path, text.as_bytes(), "--json"));
    }
    if let (Some(path), Some(text)) = (&args.save_model, &saved) {
        outputs.push((path, text.as_bytes(), "--save-model"));
    }
    super::common::write_outputs(&outputs, &inputs, args.strict, report.warnings.len())
}

/// Without `--offset`: whether a constant term would help, judged as `order` judges it
/// (`sysid::order::offset_hint`) on ARX of the same lags, estimated on the first part of the
/// estimation record and ranked on its last `--selection` fraction (audit s12 F8).
fn offset_hint(est: &sysid::Dataset, s: &NarxSettings) -> Option<String> {
    if s.constant {
        return None;
    }
    let n = est.len();
    let k = sysid::data::split_rows(n, 1.0 - s.selection).ok()?;
    let arx = sysid::Identification::default()
        .with_kind(sysid::ModelKind::Arx)
        .with_method(sysid::Method::Ls);
    sysid::order::offset_hint(
        (&est.rows(0..k), Some(&est.rows(k..n))),
        &arx,
        (
            sysid::Orders {
                na: s.na,
                nb: s.nb,
                nk: s.nk,
            },
            None,
            None,
        ),
        (
            &format!(
                "ARX of the same lags ({}, {}, {}), by ls,",
                s.na, s.nb, s.nk
            ),
            "identify again with --offset (it offers the NARX model the constant term)",
        ),
    )
}

fn opt(v: Option<f64>, unit: &str) -> String {
    v.map_or("n/a (the simulation blew up)".into(), |v| {
        format!("{}{unit}", report::format::num(v))
    })
}

/// The text summary of a NARX identification.
fn render(r: &NarxReport, s: &NarxSettings) -> String {
    use std::fmt::Write;
    let m = &r.model;
    let mut t = String::new();
    let _ = writeln!(
        t,
        "Polynomial NARX: na = {}, nb = {}, nk = {}, degree {}{}; {} of {} candidate terms chosen by FROLS \
         (stopping rule {}{}), Σ ERR = {:.6}",
        m.na(),
        m.nb(),
        m.nk(),
        m.degree(),
        if s.constant { ", constant offered" } else { "" },
        r.terms.len(),
        r.selection.candidates,
        r.selection.stop.rule,
        r.selection
            .selection_fraction
            .map(|f| format!(" on the last {:.0} % of the estimation record", 100.0 * f))
            .unwrap_or_default(),
        r.selection.err_sum
    );
    let _ = writeln!(
        t,
        "  {:<28} {:>14} {:>12} {:>10}",
        "term", "coefficient", "std", "ERR"
    );
    for term in &r.terms {
        let _ = writeln!(
            t,
            "  {:<28} {:>14} {:>12} {:>10.6}",
            term.term,
            report::format::num(term.coefficient),
            term.std.map_or("n/a".into(), report::format::num),
            term.err
        );
    }
    if let Some(f) = &r.refinement {
        let _ = writeln!(
            t,
            "Simulation-error refinement: estimation RMSE {} -> {} in {} iteration(s){}",
            report::format::num(f.rmse_before),
            report::format::num(f.rmse_after),
            f.iterations,
            if f.converged { "" } else { " (not converged)" }
        );
    }
    let na = |v: Option<f64>| v.map_or("n/a".to_string(), report::format::num);
    let mut line = |name: &str, x: &sysid::narx::NarxMetrics| {
        let _ = writeln!(
            t,
            "{name} ({}, {} rows): simulation RMSE {}, fit {} (initial outputs measured); one-step RMSE {}; \
             MATLAB's LossFcn {}, FPE {}, nAIC {} (one-step prediction errors)",
            x.data,
            x.n,
            opt(x.rmse_sim, ""),
            opt(x.fit_sim_percent, " %"),
            report::format::num(x.rmse_pred),
            na(x.loss_fcn),
            na(x.fpe_matlab),
            na(x.aic_matlab)
        );
    };
    line("Estimation", &r.metrics.estimation);
    if let Some(v) = &r.metrics.validation {
        line("Validation", v);
    }
    for w in &r.warnings {
        let _ = writeln!(t, "warning: {w}");
    }
    t
}
