//! `ipa-sysid order --classes ...`: the structure search over model classes (`sysid::search`), ranked on
//! the selection part of the estimation record; the chosen one re-estimated on the whole estimation
//! record and reported on the test record, which the ranking never sees.

use std::path::Path;

use report::format::num;
use sysid::search::{recommended, structure_search, Class, ClassCandidate};
use sysid::{Dataset, Identification, Orders};

use super::common::{print_report, progress_bar, write_outputs};
use super::order::Args;

/// The chosen candidate on the test record.
#[derive(Debug, serde::Serialize)]
struct Chosen {
    class: String,
    orders: Orders,
    /// Re-estimated on this record (estimation and selection parts together).
    estimated_on: String,
    /// The test record, if given.
    data: Option<String>,
    /// Free-run RMSE on the test record from its measured initial outputs.
    rmse_sim: Option<f64>,
    fit_sim_percent: Option<f64>,
}

/// Runs the class search: `records` = (whole estimation record, estimation part, selection part,
/// test record), `grid` = (na, nb, nk) values, `inputs` the input files and `warnings` those found
/// before the search (the test record's rows, a short selection part), `notes` the reader's (printed
/// already; they join the JSON's warnings and count for `--strict`).
pub fn run(
    args: &Args,
    base: &Identification,
    records: (&Dataset, &Dataset, &Dataset, Option<&Dataset>),
    grid: (&[usize], &[usize], &[usize]),
    (inputs, mut warnings, notes): (&[&Path], Vec<String>, &[String]),
) -> anyhow::Result<()> {
    let (data, fit_part, selection, test) = records;
    if data.inputs().len() != 1 {
        anyhow::bail!("--classes searches single-input structures; choose one input with --u-col");
    }
    let orders: Vec<Orders> = grid
        .0
        .iter()
        .flat_map(|&na| {
            grid.1
                .iter()
                .flat_map(move |&nb| grid.2.iter().map(move |&nk| Orders { na, nb, nk }))
        })
        .collect();
    let narx = args
        .narx
        .settings((2, 2, 1), 2, args.offset, 100, args.memory.max_memory);
    narx.check()?;
    let bar = progress_bar(
        (orders.len() * args.classes.len()) as u64,
        "{bar:40} {pos}/{len} structures {elapsed}",
    );
    if args.selection_rows.is_some() {
        anyhow::bail!(
            "--classes ranks on the last part of the estimation record (--selection-split), not on --selection-rows"
        );
    }
    let split = fit_part.len();
    sysid::search::check_memory(data, fit_part, &args.classes, &orders, base, &narx)?;
    let ranked = structure_search(data, split, &args.classes, &orders, base, &narx, &|| {
        bar.inc(1)
    });
    bar.finish_and_clear();
    let chosen = match recommended(&ranked) {
        None => {
            warnings.push(
                "no structure qualifies (every candidate failed, blew up, simulates the selection part \
                 worse than its mean, or carries another disqualifying warning): none is recommended"
                    .to_string(),
            );
            None
        }
        Some(c) => {
            let name = |c: &ClassCandidate| {
                format!(
                    "{} ({}, {}, {})",
                    c.class, c.orders.na, c.orders.nb, c.orders.nk
                )
            };
            // The candidate of least selection RMSE, when a warning passed it over.
            let passed = ranked
                .iter()
                .filter(|d| d.selection_rmse.is_some() && d.error.is_none())
                .min_by(|a, b| {
                    let k = |c: &ClassCandidate| c.selection_rmse.unwrap_or(f64::INFINITY);
                    k(a).total_cmp(&k(b)).then(a.p.cmp(&b.p))
                })
                .filter(|d| !d.qualified());
            if let Some(d) = passed {
                warnings.push(format!(
                    "the candidate of least selection RMSE, {}, is not recommended because {}: \
                     recommended instead the best qualifying candidate, {}",
                    name(d),
                    d.disqualified
                        .as_deref()
                        .unwrap_or("its selection fit is negative or it is unstable"),
                    name(c)
                ));
            }
            warnings.extend(
                c.warnings
                    .iter()
                    .map(|w| format!("recommended {}: {w}", name(c))),
            );
            if args.detrend == sysid::detrend::Detrend::None {
                // Whether a constant term would help, judged on ARX of the recommended orders (the
                // hint plain `order` gives; audit s12 F8).
                let o = c.orders;
                warnings.extend(sysid::order::offset_hint(
                    (fit_part, Some(selection)),
                    &base.clone().with_kind(sysid::ModelKind::Arx),
                    (o, None, None),
                    (
                        &format!(
                            "ARX of the recommended orders ({}, {}, {}), by {},",
                            o.na,
                            o.nb,
                            o.nk,
                            sysid::Estimator::method(&base.estimator)
                        ),
                        "search again with --offset (it offers every class the constant term)",
                    ),
                ));
            }
            let chosen = chosen_on_test(
                c,
                base,
                &narx,
                data,
                test,
                split as f64 / data.len() as f64,
                &mut warnings,
            )?;
            if let (Some(t), None) = (&chosen.data, chosen.rmse_sim) {
                warnings.push(format!(
                    "the chosen structure's free-run simulation diverged or blew up on the test record {t}: \
                     the selection part did not reveal it; try the next candidates or a lower degree"
                ));
            }
            Some(chosen)
        }
    };
    let ranked_by = "free-run RMSE on the selection part (from its measured initial outputs), then fewer \
                     parameters; candidates a warning disqualifies (unstable or blowing up, negative \
                     selection fit, not converged, worse than the linear start or baseline, nonlinearity \
                     not physical, no input term) last";
    let o = |v: Option<f64>| v.map_or_else(|| "n/a".to_string(), num);
    let mut text = format!(
        "Structure search: {} candidates ({} classes x {} orders) estimated on {} ({} samples), ranked on \
         {} ({} samples) by {ranked_by}\n\n",
        ranked.len(),
        args.classes.len(),
        orders.len(),
        fit_part.name(),
        fit_part.len(),
        selection.name(),
        selection.len()
    );
    text.push_str(&format!(
        "{:>4} {:<24} {:>3} {:>3} {:>3} {:>4} {:>12} {:>10} {:>10}\n",
        "rank", "class", "na", "nb", "nk", "p", "RMSE sel", "fit sel %", "AIC"
    ));
    for (i, c) in ranked.iter().take(args.top).enumerate() {
        text.push_str(&format!(
            "{:>4} {:<24} {:>3} {:>3} {:>3} {:>4} {:>12} {:>10} {:>10}{}\n",
            i + 1,
            c.class,
            c.orders.na,
            c.orders.nb,
            c.orders.nk,
            c.p,
            o(c.selection_rmse),
            o(c.selection_fit_percent),
            o(c.aic),
            match (&c.error, c.qualified()) {
                (Some(e), _) => format!("  ({e})"),
                (None, false) => "  (disqualified)".to_string(),
                (None, true) => String::new(),
            }
        ));
    }
    // The AIC column's n/a for output-nonlinear classes, said once under the table (audit s28 L-2).
    let mut no_aic: Vec<&str> = Vec::new();
    for c in ranked
        .iter()
        .take(args.top)
        .filter(|c| c.aic_note.is_some())
    {
        if !no_aic.contains(&c.class.as_str()) {
            no_aic.push(&c.class);
        }
    }
    if let Some(note) = ranked.iter().find_map(|c| c.aic_note) {
        if !no_aic.is_empty() {
            text.push_str(&format!("AIC of {}: {note}\n", no_aic.join(", ")));
        }
    }
    if let Some(c) = &chosen {
        text.push_str(&format!(
            "\nChosen: {} (na, nb, nk) = ({}, {}, {}), re-estimated on {}{}\n",
            c.class,
            c.orders.na,
            c.orders.nb,
            c.orders.nk,
            c.estimated_on,
            match &c.data {
                Some(d) => format!(
                    ": test RMSE {} (simulation from measured initial outputs), fit {} % on {d} (never used for ranking)",
                    o(c.rmse_sim),
                    o(c.fit_sim_percent)
                ),
                None => "; no test record: the selection figures are optimistic".into(),
            }
        ));
    }
    for w in &warnings {
        text.push_str(&format!("warning: {w}\n"));
    }
    print_report(&text, &[args.json.as_deref()])?;
    let warnings: Vec<String> = super::common::data_notes(notes).chain(warnings).collect();
    let mut json = None;
    if args.json.is_some() {
        #[derive(serde::Serialize)]
        struct Doc<'a> {
            search: &'static str,
            data: &'a str,
            selection: &'a str,
            validation: Option<&'a str>,
            ranked_by: &'static str,
            chosen: Option<Chosen>,
            warnings: &'a [String],
            candidates: &'a [ClassCandidate],
        }
        let doc = Doc {
            search: "classes",
            data: fit_part.name(),
            selection: selection.name(),
            validation: test.map(Dataset::name),
            ranked_by,
            chosen,
            warnings: &warnings,
            candidates: &ranked,
        };
        json = Some(super::common::report_json(&doc, true)? + "\n");
    }
    let mut outputs: Vec<(&Path, &[u8], &str)> = Vec::new();
    if let (Some(path), Some(text)) = (&args.json, &json) {
        outputs.push((path, text.as_bytes(), "--json"));
    }
    // With --strict and warnings, --json is not written (an earlier file stays) and the exit code is 1.
    write_outputs(&outputs, inputs, args.strict, warnings.len())
}

/// The chosen candidate re-estimated on the whole estimation record, with its test figures; the test
/// record's warnings (as plain `order` gives them) are added to `warnings`.
fn chosen_on_test(
    c: &ClassCandidate,
    base: &Identification,
    narx: &sysid::narx::NarxSettings,
    data: &Dataset,
    test: Option<&Dataset>,
    split_fraction: f64,
    warnings: &mut Vec<String>,
) -> anyhow::Result<Chosen> {
    let class: Class = c.class.parse().map_err(anyhow::Error::msg)?;
    let o = c.orders;
    let (rmse_sim, fit) = match class {
        Class::Narx(degree) => {
            // What the search ranked: the sim rule on the same split (the same computation).
            let s = sysid::narx::NarxSettings {
                na: o.na,
                nb: o.nb,
                nk: o.nk,
                degree,
                stop: sysid::narx::StopRule::Sim,
                selection: 1.0 - split_fraction,
                ..narx.clone()
            };
            let fit = sysid::narx::identify_narx(data, &s)?;
            match test {
                Some(t) => {
                    let m = sysid::narx::narx_metrics(&fit.model, t)?;
                    warnings.extend(
                        sysid::narx::narx_trust(
                            sysid::warnings::Record::Test,
                            &fit.model,
                            s.constant,
                            data,
                            t,
                            &m,
                        )
                        .iter()
                        .map(super::order::test_record_words),
                    );
                    (m.rmse_sim, m.fit_sim_percent)
                }
                None => (None, None),
            }
        }
        Class::Input(_) | Class::Wiener(_) => {
            let id = class
                .identification(base, o)
                .ok_or_else(|| anyhow::anyhow!("no identification for {class}"))?;
            let fit = sysid::estimate::identify(data, &id)?;
            match test {
                Some(t) => {
                    let m = sysid::metrics::metrics(&fit.model, t)?;
                    warnings.extend(super::order::test_record_warnings(&fit, &id, data, t, &m));
                    (m.rmse_sim_measured, m.fit_sim_measured_percent)
                }
                None => (None, None),
            }
        }
    };
    // The test fit far below the selection fit that chose the candidate (audit s21 M-A1), as plain
    // `order` says it; both from the measured initial outputs.
    warnings.extend(
        sysid::trust::held_out_drop(
            (sysid::warnings::Record::Selection, c.selection_fit_percent),
            (sysid::warnings::Record::Test, fit),
        )
        .map(|w| super::order::test_record_words(&w)),
    );
    Ok(Chosen {
        class: c.class.clone(),
        orders: o,
        estimated_on: data.name().to_string(),
        data: test.map(|t| t.name().to_string()),
        rmse_sim,
        fit_sim_percent: fit,
    })
}
