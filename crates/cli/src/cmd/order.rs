//! `ipa-sysid order`: rank model orders and delays (MATLAB `arxstruc`/`selstruc`) by validation fit, AIC
//! and FPE; the search itself is `sysid::order::search` (parallel).

use std::path::{Path, PathBuf};

use sysid::estimate::{IdentifySettings, Method};
use sysid::order::{grid_size, parse_range, search, Candidate};
use sysid::summary::num;
use sysid::ModelKind;

use super::common::{check_outputs, progress_bar, write_output, ColumnArgs, ValidationArgs};
use super::identify::{KindArg, MethodArg};

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
    /// Model structure.
    #[arg(long, value_enum, default_value = "arx")]
    pub model: KindArg,
    /// Estimator.
    #[arg(long, value_enum, default_value = "ls")]
    pub method: MethodArg,
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
    let base = IdentifySettings {
        kind: match args.model {
            KindArg::Hammerstein => ModelKind::Hammerstein,
            KindArg::Arx => ModelKind::Arx,
        },
        method: match args.method {
            MethodArg::Ls => Method::Ls,
            MethodArg::Rls => Method::Rls,
            MethodArg::Oe => Method::Oe,
            MethodArg::Iv => Method::Iv,
        },
        offset: args.offset,
        drop_unexcited_branch: true,
        ..IdentifySettings::default()
    };
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
        base.kind,
        base.method,
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
