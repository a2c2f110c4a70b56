//! `ipa-sysid reproduce`: the paper end to end (experiment, identification, validation, control, report).

use std::path::PathBuf;

use anyhow::Context;
use indicatif::{ProgressBar, ProgressStyle};
use ipa_reproduce::{run as reproduce, ReproduceSettings};

/// Flags of `reproduce`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Output folder (created if missing): report.html, summary.json, figures/, data/. An existing folder
    /// must be empty or written by a previous `reproduce` (it holds the marker file .ipa-sysid-output).
    #[arg(long, value_name = "DIR", default_value = "reproduce-out")]
    pub out: PathBuf,
    /// Plant: the physics simulator `ipa`, the paper's model `paper`, or `model:FILE`.
    #[arg(long, default_value = "ipa")]
    pub plant: String,
    /// TOML file overriding the physics plant's parameters (see `ipa-sysid plant-config`).
    #[arg(long, value_name = "FILE")]
    pub plant_config: Option<PathBuf>,
    /// Seed of the experiment (the validation record uses seed + 1).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
    /// RLS forgetting factor for both models.
    #[arg(long, default_value_t = 1.0)]
    pub forgetting: f64,
}

/// Runs `reproduce`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.out.as_os_str() == "-" {
        anyhow::bail!(
            "--out -: reproduce writes a folder of files (report, figures, data); name a folder"
        );
    }
    if args.out.is_file() {
        anyhow::bail!(
            "--out {}: is a file; expected a folder (it is created if missing)",
            args.out.display()
        );
    }
    // The run replaces files in --out: refuse an input file inside it, and a bad plant before the
    // folder is created.
    if let Ok(out) = std::fs::canonicalize(&args.out) {
        for input in ipa::spec::spec_input_files(&args.plant, args.plant_config.as_deref()) {
            if std::fs::canonicalize(input).is_ok_and(|p| p.starts_with(&out)) {
                anyhow::bail!(sysid::SysidError::setting(
                    sysid::Setting::Other("--out"),
                    args.out.display(),
                    &format!(
                        "a folder that does not hold the input file {} (the run writes into it)",
                        input.display()
                    )
                ));
            }
        }
    }
    ipa::plant_from_spec(&args.plant, args.plant_config.as_deref())?;
    sysid::rls::check_settings(args.forgetting, 1.0)?;
    let mut settings = ReproduceSettings {
        plant: args.plant.clone(),
        plant_config: args.plant_config.clone(),
        seed: args.seed,
        out_dir: args.out.clone(),
        forgetting: args.forgetting,
        ..ReproduceSettings::default()
    };
    let bar = ProgressBar::new(100);
    bar.set_style(
        ProgressStyle::with_template("{spinner} [{bar:30}] {pos:>3}% {msg}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> "),
    );
    // Never replace a user's own files: the folder must be new, empty, or written by `reproduce`. It is
    // written whole: into a temporary folder beside it, renamed into place when the run has succeeded
    // (a failure or SIGINT/SIGTERM leaves the folder as it was and no temporary folder).
    let mut outcome = None;
    let written = sysid_io::write_claimed_folder(
        &args.out,
        "--out",
        "ipa-sysid reproduce",
        |dir: &std::path::Path| -> anyhow::Result<()> {
            settings.out_dir = dir.to_path_buf();
            let run = reproduce(&settings, &mut |stage: &str, fraction: f64| {
                bar.set_position((fraction * 100.0).round() as u64);
                bar.set_message(stage.to_string());
            })?;
            outcome = Some(run);
            Ok(())
        },
    );
    bar.finish_and_clear();
    if written? {
        // The folder of an earlier run (its marker), replaced whole; files it did not write are kept.
        super::common::print_replaced(std::slice::from_ref(&args.out));
    }
    let outcome = outcome.context("reproduce did not run")?;
    let mut text = format!(
        "{}\nReport: {}\nSummary: {}\nElapsed: {:.2} s\n",
        outcome.text,
        args.out.join("report.html").display(),
        args.out.join("summary.json").display(),
        outcome.summary["elapsed_s"].as_f64().unwrap_or(f64::NAN)
    );
    if !outcome.accepted {
        text += "Note: not every acceptance criterion was met; the report says which and why.\n";
    }
    super::common::print_stdout(&text)
}
