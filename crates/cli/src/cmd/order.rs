//! `ipa-sysid order`: rank model orders and delays (MATLAB `arxstruc`/`selstruc`) by validation fit, AIC
//! and FPE; the search itself is `sysid::order::search` (parallel).

use std::path::{Path, PathBuf};

use report::format::num;
use sysid::estimate::{Identification, Method};
use sysid::model::MAX_ORDER;
use sysid::order::{grid_size, search, Candidate};
use sysid::ModelKind;

use super::common::{check_outputs, progress_bar, write_output, ColumnArgs, ValidationArgs};

/// Flags of `order`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Estimation CSV file (header row; columns chosen by --u-col, --y-col, --t-col).
    #[arg(long, value_name = "FILE")]
    pub data: PathBuf,
    #[command(flatten)]
    pub columns: ColumnArgs,
    #[command(flatten)]
    pub val: ValidationArgs,
    /// Orders of A to try: a..b (inclusive) or a single value.
    #[arg(long, default_value = "1..5")]
    pub na: String,
    /// Numbers of B coefficients to try.
    #[arg(long, default_value = "1..3")]
    pub nb: String,
    /// Input delays to try.
    #[arg(long, default_value = "0..5")]
    pub nk: String,
    /// Model structure (`--model` is an older spelling; `--model` names a model file elsewhere).
    #[arg(
        long = "structure",
        alias = "model",
        value_name = "STRUCTURE",
        value_enum,
        default_value = "arx"
    )]
    pub model: ModelKind,
    /// Estimator.
    #[arg(long, value_enum, default_value = "ls")]
    pub method: Method,
    /// Estimate a constant term c in the linear block.
    #[arg(long)]
    pub offset: bool,
    /// How many ranked structures to print (all go to --json).
    #[arg(long, default_value_t = 15)]
    pub top: usize,
    /// Write the ranking as JSON here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
}

/// Parses `a..b` (inclusive) or a single value `a`; `flag` names the option in errors.
pub fn parse_range(text: &str, flag: &'static str) -> anyhow::Result<Vec<usize>> {
    let bad = || {
        sysid::SysidError::setting(
            sysid::Setting::Other(flag),
            text,
            &format!("an order a..b (inclusive, a <= b) or a single value, at most {MAX_ORDER}"),
        )
    };
    let t = text.trim();
    let (a, b) = match t.split_once("..") {
        Some((a, b)) => (
            a.trim().parse::<usize>().map_err(|_| bad())?,
            b.trim().parse::<usize>().map_err(|_| bad())?,
        ),
        None => {
            let v = t.parse::<usize>().map_err(|_| bad())?;
            (v, v)
        }
    };
    if a > b || b > MAX_ORDER {
        return Err(bad().into());
    }
    Ok((a..=b).collect())
}

/// The JSON document of `order --json`.
#[derive(Debug, serde::Serialize)]
struct OrderReport<'a> {
    data: String,
    validation: Option<String>,
    ranked_by: &'static str,
    candidates: &'a [Candidate],
}

/// Runs `order`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let na = parse_range(&args.na, "--na")?;
    let nb = parse_range(&args.nb, "--nb")?;
    let nk = parse_range(&args.nk, "--nk")?;
    let base = Identification {
        drop_unexcited_branch: true,
        ..Identification::default()
    }
    .with_kind(args.model)
    .with_method(args.method)
    .with_offset(args.offset);
    let mut inputs: Vec<&Path> = vec![&args.data];
    inputs.extend(args.val.validation.as_deref());
    check_outputs(&[(&args.json, "--json")], &inputs)?;
    let opts = args.columns.csv_options();
    let data = sysid::data::read_csv(&args.data, &opts)?;
    let val = args.val.read(&opts)?;
    let bar = progress_bar(
        grid_size(&na, &nb, &nk) as u64,
        "{bar:40} {pos}/{len} structures {elapsed}",
    );
    let ranked = search(&data, val.as_ref(), &na, &nb, &nk, &base, &|| bar.inc(1));
    bar.finish_and_clear();
    let ranked_by = if val.is_some() {
        "validation fit % (simulation)"
    } else {
        "estimation fit % (simulation)"
    };
    let mut text = format!(
        "Order search: {} structures ({} model, {} estimator) on {}{}; ranked by {ranked_by}, then fewer parameters, then AIC\n\n",
        ranked.len(),
        base.structure.kind,
        sysid::Estimator::method(&base.estimator),
        data.name,
        val.as_ref().map(|v| format!(", validated on {}", v.name)).unwrap_or_default()
    );
    text.push_str(&format!(
        "{:>4} {:>3} {:>3} {:>3} {:>4} {:>12} {:>12} {:>12} {:>12} {:>7}\n",
        "rank", "na", "nb", "nk", "p", "fit est %", "fit val %", "AIC", "FPE", "stable"
    ));
    let o = |v: Option<f64>| v.map_or_else(|| "n/a".to_string(), num);
    for (i, c) in ranked.iter().take(args.top).enumerate() {
        text.push_str(&format!(
            "{:>4} {:>3} {:>3} {:>3} {:>4} {:>12} {:>12} {:>12} {:>12} {:>7}{}\n",
            i + 1,
            c.orders.na,
            c.orders.nb,
            c.orders.nk,
            c.p,
            o(c.fit_estimation),
            o(c.fit_validation),
            o(c.aic),
            o(c.fpe),
            if c.stable { "yes" } else { "no" },
            c.error
                .as_ref()
                .map(|e| format!("  ({e})"))
                .unwrap_or_default()
        ));
    }
    let json_to_stdout = args.json.as_deref().is_some_and(|p| p.as_os_str() == "-");
    if json_to_stdout {
        eprint!("{text}");
    } else {
        print!("{text}");
    }
    if let Some(path) = &args.json {
        let doc = OrderReport {
            data: data.name.clone(),
            validation: val.as_ref().map(|v| v.name.clone()),
            ranked_by,
            candidates: &ranked,
        };
        let json = serde_json::to_string_pretty(&doc)? + "\n";
        write_output(path, json.as_bytes(), &inputs, "--json")?;
    }
    Ok(())
}
