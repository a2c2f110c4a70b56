//! `ipa-sysid simulate --fleet N --worn FRACTION --seed S --out DIR`: a fleet of physics IPAs, some with
//! wearing valves (`ipa::fleet`), written as a folder of Parquet files of long-format records
//! (`actuator_id` INT64, `t` s, `u` counts, `y` mm; `part-00000.parquet`, … each holding `--per-file`
//! whole actuators, rows by actuator then time) and `truth.csv` (`actuator_id,worn`). The folder is
//! written as a whole (`sysid_io::write_folder`): an existing folder with files is refused unless
//! `--overwrite`, and even then unless it holds only what a fleet run writes. Actuators are simulated in parallel (rayon); the files do not depend on the threads.

use std::path::Path;

use rayon::prelude::*;
use sysid_io::parquet::{write_parquet, Column};

use super::simulate::Args;

/// Runs `simulate --fleet`.
pub fn run(args: &Args) -> anyhow::Result<()> {
    let ignored = [
        (args.plant != "ipa", "--plant"),
        (args.plant_config.is_some(), "--plant-config"),
        (args.input != "staircase", "--input"),
        (args.ts.is_some(), "--ts"),
        (args.noise_std != 0.0, "--noise-std"),
        (args.amplitude != 255.0, "--amplitude"),
        (args.y0.is_some(), "--y0"),
    ];
    if let Some((_, flag)) = ignored.iter().find(|(on, _)| *on) {
        anyhow::bail!(
            "{flag} is not available with --fleet: each actuator runs the staircase experiment on its own \
             physics plant (docs/fleet.md)"
        );
    }
    let design = ipa::fleet::FleetDesign {
        actuators: args.fleet.unwrap_or_default(),
        worn_fraction: args.worn,
        windows: args.windows,
        samples_per_window: args.samples.unwrap_or(ipa::experiment::DEFAULT_SAMPLES),
        seed: args.seed,
        ..ipa::fleet::FleetDesign::default()
    };
    design.check()?;
    if args.per_file == 0 || args.per_file > ipa::fleet::MAX_ACTUATORS {
        anyhow::bail!(sysid::SysidError::setting(
            sysid::Setting::Other("--per-file"),
            args.per_file,
            &format!("1..={} actuators per file", ipa::fleet::MAX_ACTUATORS)
        ));
    }
    let worn = design.worn();
    let ids: Vec<usize> = (0..design.actuators).collect();
    let files = ids.chunks(args.per_file).count();
    // Checked with or without --overwrite: a folder holding the user's own files gets "choose another
    // --out", never the advice to pass --overwrite (audit s23 L-B7).
    sysid_io::check_folder_path(&args.out, "--out")?;
    check_fleet_folder(&args.out)?;
    let replaced = sysid_io::write_folder(&args.out, "--out", args.overwrite, |dir: &Path| {
        ids.chunks(args.per_file)
            .enumerate()
            .try_for_each(|(f, chunk)| {
                write_part(&design, &worn, chunk, &dir.join(part_name(f)))
            })?;
        let rows = worn
            .iter()
            .enumerate()
            .map(|(i, w)| vec![i.to_string(), w.to_string()]);
        sysid_io::write_csv(&dir.join("truth.csv"), &["actuator_id", "worn"], rows)?;
        anyhow::Ok(())
    })?;
    if replaced {
        super::common::print_replaced(std::slice::from_ref(&args.out));
    }
    eprintln!(
        "wrote {} actuators ({} worn) × {} windows of {} samples to {} ({files} Parquet file(s) and truth.csv)",
        design.actuators,
        worn.iter().filter(|w| **w).count(),
        design.windows,
        design.samples_per_window,
        args.out.display()
    );
    Ok(())
}

/// An existing `--out` folder can be replaced (with `--overwrite`) only when it holds nothing but what
/// a fleet run writes (`part-NNNNN.parquet` and `truth.csv`, plain files): a mistyped `--out ~/data
/// --overwrite` must not remove a folder of the user's records (audit s13 M7), and without
/// `--overwrite` such a folder is not answered with the advice to pass it (audit s23 L-B7).
fn check_fleet_folder(dir: &Path) -> anyhow::Result<()> {
    let entries = match std::fs::read_dir(dir) {
        Ok(entries) => entries,
        // Missing (or not a folder: `write_folder` names that).
        Err(_) => return Ok(()),
    };
    let is_fleet_file = |name: &str| {
        name == "truth.csv"
            || name
                .strip_prefix("part-")
                .and_then(|r| r.strip_suffix(".parquet"))
                .is_some_and(|n| n.len() == 5 && n.bytes().all(|b| b.is_ascii_digit()))
    };
    let mut others = Vec::new();
    for e in entries {
        let e = e.map_err(|e| anyhow::anyhow!("{}: {e}", dir.display()))?;
        let name = e.file_name().to_string_lossy().into_owned();
        let plain = e.file_type().is_ok_and(|t| t.is_file());
        if !(plain && is_fleet_file(&name)) {
            others.push(name);
        }
    }
    if others.is_empty() {
        return Ok(());
    }
    others.sort();
    let shown = others
        .iter()
        .take(5)
        .cloned()
        .collect::<Vec<_>>()
        .join(", ");
    anyhow::bail!(sysid::SysidError::setting(
        sysid::Setting::Other("--out"),
        dir.display(),
        &format!(
            "a new or empty folder, or (with --overwrite) one written by an earlier `simulate --fleet` \
             (only part-NNNNN.parquet and truth.csv); this one also holds {} other entr{} ({shown}{}), \
             which --overwrite would remove: choose another --out",
            others.len(),
            if others.len() == 1 { "y" } else { "ies" },
            if others.len() > 5 { ", ..." } else { "" }
        )
    ));
}

/// The name of Parquet file `f`.
fn part_name(f: usize) -> String {
    format!("part-{f:05}.parquet")
}

/// Simulates the actuators `ids` (in parallel) and writes them as one Parquet file.
fn write_part(
    design: &ipa::fleet::FleetDesign,
    worn: &[bool],
    ids: &[usize],
    path: &Path,
) -> anyhow::Result<()> {
    let windows: Vec<Vec<ipa::fleet::FleetWindow>> = ids
        .par_iter()
        .map(|&i| design.actuator(i, worn[i]))
        .collect::<Result<_, _>>()?;
    let rows: usize = windows.iter().flatten().map(|w| w.record.u.len()).sum();
    let (mut id, mut t, mut u, mut y) = (
        Vec::with_capacity(rows),
        Vec::with_capacity(rows),
        Vec::with_capacity(rows),
        Vec::with_capacity(rows),
    );
    for w in windows.iter().flatten() {
        let n = w.record.u.len();
        id.extend(std::iter::repeat_n(w.actuator_id as i64, n));
        let k0 = w.window * design.samples_per_window;
        t.extend((0..n).map(|k| (k0 + k) as f64 * w.record.ts));
        u.extend_from_slice(&w.record.u);
        y.extend_from_slice(&w.record.y);
    }
    write_parquet(
        path,
        &[
            Column::Int64("actuator_id", &id),
            Column::Double("t", &t),
            Column::Double("u", &u),
            Column::Double("y", &y),
        ],
    )?;
    Ok(())
}
