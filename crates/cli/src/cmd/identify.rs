//! `ipa-sysid identify`: a model from a CSV of input/output data (MATLAB `arx`, plus the Hammerstein model).

use std::path::{Path, PathBuf};

use sysid::data::stream::{CsvStream, RecordSource};
use sysid::rls_ud::RlsForm;
use sysid::windup::Windup;
use sysid::{identify, Dataset, Identification, InputSpec, Method, NonlinearityKind, Passes};
use sysid::{IdentifyOptions, ModelKind};
use sysid_summary::IdentifyReport;

use super::common::{
    check_outputs, same_samples, same_samples_warning, shared_rows_warning, stream_note,
    ColumnArgs, FileRows, StreamMode, ValidationArgs,
};
use sysid::detrend::{detrend, Detrend};

/// One order per input (`--nb 2,1`; one value applies to every input).
#[derive(Debug, Clone, PartialEq)]
pub struct OrderList(pub Vec<usize>);

impl OrderList {
    /// The first (for one input: the only) value.
    pub fn first(&self) -> usize {
        self.0.first().copied().unwrap_or(0)
    }

    /// The value for each of `n` inputs: one value applies to all; fails (naming `flag`) unless there is
    /// one value or one per input.
    pub fn per_input(&self, n: usize, flag: &'static str) -> anyhow::Result<Vec<usize>> {
        match self.0.len() {
            1 => Ok(vec![self.first(); n]),
            m if m == n => Ok(self.0.clone()),
            m => Err(sysid::SysidError::setting(
                sysid::Setting::Other(flag),
                format!("{m} values"),
                &format!("one value for every input, or one per input ({n} inputs)"),
            )
            .into()),
        }
    }
}

/// Parses `--nb 2` or, with several inputs, `--nb 2,1`.
fn parse_order_list(text: &str) -> Result<OrderList, String> {
    text.split(',')
        .map(parse_order)
        .collect::<Result<_, _>>()
        .map(OrderList)
}

/// Parses one order (`--na 3`); a range such as `1..5` points to `order`, which compares structures.
fn parse_order(text: &str) -> Result<usize, String> {
    if text.contains("..") {
        return Err(format!(
            "identify fits one structure; to compare orders {text} use `ipa-sysid order --na 1..5 --nb 1..3 \
             --nk 0..5` (it ranks them by fit, AIC and FPE), then identify the chosen one"
        ));
    }
    text.trim()
        .parse()
        .map_err(|e| format!("{e}; expected a whole number >= 0"))
}

/// An estimator setting as its flag (`--max-trace`) and what uses it in words, with the methods as
/// flags: "the recursive estimators (--method rls or iv)" ([`sysid::EstimatorSetting`], the one table
/// the Python module also checks).
fn method_flag(s: sysid::EstimatorSetting) -> (String, String) {
    let methods = s
        .methods()
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(" or ");
    (
        format!("--{}", s.id().replace('_', "-")),
        format!("{} (--method {methods})", s.whose()),
    )
}

/// Flags of `identify`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// CSV file with a header row (columns chosen by --u-col, --y-col, --t-col), or a MATLAB .mat file.
    /// Several files or a folder (its *.csv and *.mat records) identify each in parallel: one JSON line
    /// per file to --json or stdout.
    #[arg(long, value_name = "FILE", num_args = 1.., required = true)]
    pub data: Vec<PathBuf>,
    #[command(flatten)]
    pub columns: ColumnArgs,
    /// Model structure (`--model` is an older spelling; `--model` names a model file elsewhere). Default:
    /// the paper's Hammerstein model; `order` and `delay` search linear (arx) structures, as MATLAB's
    /// `arxstruc` and `delayest` do.
    #[arg(
        long = "structure",
        alias = "model",
        value_name = "STRUCTURE",
        value_enum,
        default_value = "hammerstein"
    )]
    pub model: StructureArg,
    #[command(flatten)]
    pub narx: super::identify_narx::NarxArgs,
    /// na: number of poles (order of A); for narx the largest output lag.
    #[arg(long, default_value_t = 3, value_parser = parse_order)]
    pub na: usize,
    /// nb: number of B coefficients (>= 1 for Hammerstein); with several inputs one per input (2,1) or
    /// one for all.
    #[arg(long, default_value = "1", value_parser = parse_order_list)]
    pub nb: OrderList,
    /// nk: input delay in samples; with several inputs one per input (1,2) or one for all.
    #[arg(long, default_value = "1", value_parser = parse_order_list)]
    pub nk: OrderList,
    /// The static nonlinearity of every input (`linear`, `deadzone`, `saturation`, `deadzone-saturation`,
    /// `piecewise-linear`, `polynomial`), or of each input by name (`u1=deadzone,u2=linear`, MATLAB
    /// idnlhw's InputNonlinearity); default: --structure's (hammerstein: deadzone, arx: linear).
    #[arg(long, value_name = "KIND|NAME=KIND,...", value_parser = parse_nonlinearity)]
    pub nonlinearity: Option<NonlinearityArg>,
    /// K: breakpoints of every `piecewise-linear` nonlinearity (1..8; default 2), or `auto`: K = 1..4 tried,
    /// the smallest AIC on the estimation data kept.
    #[arg(long, value_name = "K|auto", value_parser = parse_breakpoints)]
    pub breakpoints: Option<usize>,
    /// D: degree of every `polynomial` input nonlinearity (1..8; default 3); with --structure narx the
    /// largest degree of a NARX monomial (1..5; default 2).
    #[arg(long, value_name = "D")]
    pub degree: Option<usize>,
    /// A static nonlinearity y = g(v) on the output v of the linear block (Wiener; Hammerstein–Wiener
    /// with --nonlinearity): `saturation`, `piecewise-linear` (--breakpoints K) or `polynomial`
    /// (--degree D), fitted by output error from the method's model (MATLAB idnlhw's
    /// OutputNonlinearity).
    #[arg(long, value_name = "KIND")]
    pub output_nonlinearity: Option<NonlinearityKind>,
    /// Several inputs (--u-col u1,u2) with --structure hammerstein: these inputs are linear (no deadzone);
    /// the same as --nonlinearity NAME=linear.
    #[arg(long, value_name = "NAME,...", value_delimiter = ',')]
    pub linear_inputs: Vec<String>,
    /// Estimator. Default: the paper's recursive least squares (`order` defaults to ls, its closed form).
    #[arg(long, value_enum, default_value = "rls")]
    pub method: Method,
    /// RLS forgetting factor ρ in (0, 1].
    #[arg(long, default_value_t = 1.0)]
    pub forgetting: f64,
    /// RLS initial covariance P(0) = p0 · I.
    #[arg(long, default_value_t = 1e6)]
    pub p0: f64,
    /// RLS passes over the data: `auto` (default) repeats passes until the estimate settles (at most
    /// 100); `1` is the paper's single pass; N runs exactly N (later passes restart P and refine).
    #[arg(long, default_value = "auto", value_parser = parse_passes)]
    pub passes: Passes,
    /// Maximum iterations of the key-term iteration (Hammerstein with --method ls) and of the
    /// output-error search (--method oe).
    #[arg(long, default_value_t = 100)]
    pub max_iterations: usize,
    /// RLS covariance form.
    #[arg(long, value_enum, default_value = "standard")]
    pub rls_form: RlsForm,
    /// RLS covariance-windup protection (for long records with periods without excitation).
    #[arg(long, value_enum, default_value = "none")]
    pub windup: Windup,
    /// Bound on tr P for --windup trace (default: p0 times the number of parameters).
    #[arg(long, value_name = "T")]
    pub max_trace: Option<f64>,
    /// IV stages (each rebuilds the instruments from the previous stage's model).
    #[arg(long, default_value_t = 10)]
    pub iv_stages: usize,
    /// Estimate a constant term c in the linear block.
    #[arg(long)]
    pub offset: bool,
    /// Remove the estimation record's operating point from u and y (MATLAB `detrend`): `mean` (ū, ȳ) or
    /// `linear` (a straight line per signal). The model stores (u0, y0) = (ū, ȳ) (one u0 per input) and
    /// puts it back in validate, simulate and control.
    #[arg(long, value_enum, default_value = "none")]
    pub detrend: Detrend,
    /// Several --data files: estimate ONE model from all of them (MATLAB `merge`; no regression row spans
    /// two records), with metrics per record and pooled, by least squares or RLS, with one input or
    /// several (--u-col u1,u2).
    #[arg(long)]
    pub merge: bool,
    #[command(flatten)]
    pub val: ValidationArgs,
    /// Lags M of the residual analysis (autocorrelation τ = 1..M, cross-correlation τ = −M..M), 1 to
    /// 1000: the independence test factors a (2M+1)² matrix (O(M²) memory, O(M³) time).
    #[arg(long, default_value_t = sysid::residuals::DEFAULT_MAX_LAG, value_name = "M",
          value_parser = super::common::parse_lags)]
    pub resid_lags: usize,
    /// Hammerstein: when the estimate diverges, is unstable or simulates the estimation data far worse
    /// (10 fit points) than the linear ARX model of the same orders, return that linear model written
    /// as a Hammerstein model (b_l = b_r = 0) instead; a warning says so either way.
    #[arg(long)]
    pub fallback: bool,
    /// Exit with code 1 when the result carries warnings (they are printed either way), without writing
    /// the output files (an earlier file there is kept).
    #[arg(long)]
    pub strict: bool,
    /// Write the JSON summary here (`-` for standard output).
    #[arg(long, value_name = "OUT")]
    pub json: Option<PathBuf>,
    /// Save the model for `validate --model` and `--plant model:FILE` (`-`: standard output; the text
    /// report then goes to standard error, and no other output may be `-`).
    #[arg(long, value_name = "MODEL.json")]
    pub save_model: Option<PathBuf>,
    /// Read the record in passes with bounded memory (ARX by least squares; docs/data.md, "Long
    /// records"): `auto` streams a CSV file of 64 MiB or more when the identification allows it;
    /// `--stream` alone is `on`.
    #[arg(long, value_enum, default_value = "auto", num_args = 0..=1, default_missing_value = "on", value_name = "WHEN")]
    pub stream: StreamMode,
    #[command(flatten)]
    pub memory: super::common::MemoryArgs,
    /// The ids (field names, e.g. `max_terms`) of the flags typed on the command line, a flag given at
    /// its default value included (filled by `main` from clap's matches): [`Args::check_flags`] refuses
    /// the ones this structure and method would ignore.
    #[arg(skip)]
    pub given: Vec<String>,
}

/// `--structure`: a linear or Hammerstein model (sysid's [`ModelKind`]) or a polynomial NARX model.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum StructureArg {
    /// Linear ARX: x = u.
    Arx,
    /// Hammerstein: static nonlinearity x = f(u) of each input (default deadzone), then ARX on x.
    Hammerstein,
    /// Polynomial NARX: y(k) = Σ θ_i · monomials up to --degree of y(k−1..k−na), u(k−nk..k−nk−nb+1).
    Narx,
}

impl StructureArg {
    /// The linear or Hammerstein structure (NARX is identified on its own path).
    pub fn kind(self) -> ModelKind {
        match self {
            StructureArg::Hammerstein => ModelKind::Hammerstein,
            StructureArg::Arx | StructureArg::Narx => ModelKind::Arx,
        }
    }
}

/// `--nonlinearity`: one kind for every input, or one per named input.
#[derive(Debug, Clone, PartialEq)]
pub enum NonlinearityArg {
    /// `--nonlinearity deadzone`.
    All(NonlinearityKind),
    /// `--nonlinearity u1=deadzone,u2=linear`.
    PerInput(Vec<(String, NonlinearityKind)>),
}

/// Parses `--nonlinearity`.
fn parse_nonlinearity(text: &str) -> Result<NonlinearityArg, String> {
    if !text.contains('=') {
        return text.parse().map(NonlinearityArg::All);
    }
    text.split(',')
        .map(|part| match part.split_once('=') {
            Some((name, kind)) => Ok((name.trim().to_string(), kind.parse()?)),
            None => Err(format!(
                "'{part}' names no input; expected NAME=KIND, e.g. u1=deadzone,u2=linear"
            )),
        })
        .collect::<Result<_, _>>()
        .map(NonlinearityArg::PerInput)
}

/// `--breakpoints`: a number of breakpoints from 1, or `auto` ([`sysid::blocks::AUTO_BREAKPOINTS`]).
fn parse_breakpoints(text: &str) -> Result<usize, String> {
    match text.trim() {
        "auto" => Ok(sysid::blocks::AUTO_BREAKPOINTS),
        t => match t.parse::<usize>() {
            Ok(k) if k >= 1 => Ok(k),
            _ => Err(format!(
                "'{t}' is not a number of breakpoints; expected a whole number from 1 to {}, or auto",
                sysid::nonlinearity::MAX_BREAKPOINTS
            )),
        },
    }
}

/// `--passes`: a whole number of passes, or `auto`.
fn parse_passes(text: &str) -> Result<Passes, String> {
    match text.trim() {
        "auto" => Ok(Passes::AUTO),
        t => t.parse::<usize>().map(Passes::Fixed).map_err(|_| {
            format!("'{t}' is not a number of passes; expected a whole number such as 1, or auto")
        }),
    }
}

impl Args {
    /// The identification these flags describe: one input, or one [`InputSpec`] per input of
    /// `--u-col u1,u2` (orders from `--nb`/`--nk` lists, nonlinearity from `--nonlinearity`,
    /// `--linear-inputs` or `--structure`).
    pub fn settings(&self) -> anyhow::Result<Identification> {
        Ok(self
            .settings_inputs()?
            .with_output_nonlinearity(self.output_nonlinearity.map(|k| self.sized(k))))
    }

    /// Whether the flag of field `id` (e.g. `max_terms`) was typed on the command line.
    fn given(&self, id: &str) -> bool {
        self.given.iter().any(|g| g == id)
    }

    /// Whether some input or output block is of a kind `is` accepts.
    fn any_block(&self, is: impl Fn(&NonlinearityKind) -> bool) -> bool {
        (match &self.nonlinearity {
            Some(NonlinearityArg::All(k)) => is(k),
            Some(NonlinearityArg::PerInput(list)) => list.iter().any(|(_, k)| is(k)),
            None => false,
        }) || self.output_nonlinearity.as_ref().is_some_and(is)
    }

    /// Refuses, naming the flag and why, every flag this structure and method would ignore (the one
    /// place for such checks; audit s12 F9): a flag accepted and silently ignored suggests a model
    /// that is not the one made.
    pub fn check_flags(&self) -> anyhow::Result<()> {
        if self.breakpoints.is_some()
            && !self.any_block(|k| matches!(k, NonlinearityKind::PiecewiseLinear { .. }))
        {
            anyhow::bail!(sysid::SysidError::setting(
                sysid::Setting::Other("--breakpoints"),
                self.breakpoints.unwrap_or_default(),
                "--nonlinearity or --output-nonlinearity piecewise-linear (it sets the number of breakpoints of that kind)"
            ));
        }
        let refuse = |flag: &str, why: &str| -> anyhow::Result<()> {
            anyhow::bail!("{flag} {why}; leave out {flag}")
        };
        if self.model == StructureArg::Narx {
            if self.stream == StreamMode::On {
                anyhow::bail!(sysid::stream::refused(
                    "--structure narx reads its record in memory"
                ));
            }
            if self.given("method") {
                refuse(
                    &format!("--method {}", self.method),
                    "does not apply to --structure narx: its terms are chosen by orthogonal least \
                     squares (FROLS) and their coefficients refined on the simulation error by its own \
                     Levenberg–Marquardt search (--no-refine keeps the least-squares ones)",
                )?;
            }
            if self.fallback {
                refuse(
                    "--fallback",
                    "replaces a failed Hammerstein estimate by its linear start; --structure narx has \
                     no such fallback",
                )?;
            }
            for setting in sysid::EstimatorSetting::ALL {
                if self.given(setting.id()) {
                    let (flag, what) = method_flag(setting);
                    refuse(
                        &flag,
                        &format!(
                            "is a setting of {what} for ARX, Hammerstein and Wiener models; \
                             --structure narx does not use it"
                        ),
                    )?;
                }
            }
            if self.given("resid_lags") {
                refuse(
                    "--resid-lags",
                    "sets the residual analysis of ARX, Hammerstein and Wiener models; --structure \
                     narx prints none",
                )?;
            }
            if !self.linear_inputs.is_empty() {
                refuse(
                    "--linear-inputs",
                    "is for Hammerstein models with several inputs; --structure narx has one input",
                )?;
            }
            return Ok(());
        }
        for (id, flag) in super::identify_narx::NARX_FLAGS {
            if self.given(id) {
                refuse(
                    flag,
                    &format!(
                        "is a setting of polynomial NARX models (--structure narx); this is a {} model",
                        self.structure_name()
                    ),
                )?;
            }
        }
        if let Some(d) = self.degree {
            if !self.any_block(|k| matches!(k, NonlinearityKind::Polynomial { .. })) {
                refuse(
                    &format!("--degree {d}"),
                    "sets the degree of a polynomial block (--nonlinearity or --output-nonlinearity \
                     polynomial) or of --structure narx; this structure has none",
                )?;
            }
        }
        if self.model == StructureArg::Arx {
            if let Some(kind) = self.any_input_kind(|k| *k != NonlinearityKind::Linear) {
                anyhow::bail!(
                    "--nonlinearity {kind} with --structure arx would make a Hammerstein model ({kind} + \
                     ARX), not the linear ARX model asked for: write --structure hammerstein \
                     --nonlinearity {kind} for that model, or leave out --nonlinearity for linear ARX"
                );
            }
        }
        if let Some(setting) =
            sysid::EstimatorSetting::unused_by(self.method, |s| self.given(s.id()))
        {
            let (flag, what) = method_flag(setting);
            refuse(
                &flag,
                &format!(
                    "is a setting of {what}; --method {} does not use it",
                    self.method
                ),
            )?;
        }
        Ok(())
    }

    /// The structure's name for messages: linear ARX, Hammerstein, Wiener or Hammerstein–Wiener.
    fn structure_name(&self) -> &'static str {
        match (self.model, self.output_nonlinearity.is_some()) {
            (StructureArg::Narx, _) => "polynomial NARX",
            (StructureArg::Arx, false) => "linear ARX",
            (StructureArg::Arx, true) => "Wiener",
            (StructureArg::Hammerstein, false) => "Hammerstein",
            (StructureArg::Hammerstein, true) => "Hammerstein–Wiener",
        }
    }

    /// The first input kind of `--nonlinearity` that `is` accepts.
    fn any_input_kind(&self, is: impl Fn(&NonlinearityKind) -> bool) -> Option<NonlinearityKind> {
        match &self.nonlinearity {
            Some(NonlinearityArg::All(k)) => Some(*k).filter(&is),
            Some(NonlinearityArg::PerInput(list)) => list.iter().map(|(_, k)| *k).find(&is),
            None => None,
        }
    }

    /// [`Args::settings`] without the output nonlinearity.
    fn settings_inputs(&self) -> anyhow::Result<Identification> {
        let names = self.columns.csv_options(&self.memory).input_names();
        let options = IdentifyOptions {
            model: self.model.kind(),
            na: self.na,
            nb: self.nb.first(),
            nk: self.nk.first(),
            method: self.method,
            forgetting: self.forgetting,
            p0: self.p0,
            passes: self.passes,
            max_iterations: self.max_iterations,
            rls_form: self.rls_form,
            windup: self.windup,
            max_trace: self.max_trace,
            iv_stages: self.iv_stages,
            offset: self.offset,
            fallback: self.fallback,
            max_memory: self.memory.max_memory,
        };
        if names.len() == 1 {
            if self.nb.0.len() > 1 || self.nk.0.len() > 1 || !self.linear_inputs.is_empty() {
                anyhow::bail!(
                    "--nb/--nk lists and --linear-inputs are for several inputs: name them with --u-col u1,u2"
                );
            }
            let settings = options.settings();
            return Ok(match &self.nonlinearity {
                Some(arg) => {
                    let o = settings.structure.orders;
                    let nonlinearity = self.kind_of(arg, &names[0])?;
                    settings.with_inputs(vec![InputSpec {
                        nb: o.nb,
                        nk: o.nk,
                        nonlinearity,
                    }])
                }
                None => settings,
            });
        }
        for l in &self.linear_inputs {
            if !names.contains(l) {
                anyhow::bail!(sysid::SysidError::setting(
                    sysid::Setting::Other("--linear-inputs"),
                    l,
                    &format!("names among the inputs of --u-col ({})", names.join(", "))
                ));
            }
        }
        let nb = self.nb.per_input(names.len(), "--nb")?;
        let nk = self.nk.per_input(names.len(), "--nk")?;
        let settings = options.settings();
        let default = settings.default_nonlinearity();
        let inputs = names
            .iter()
            .enumerate()
            .map(|(m, name)| {
                let nonlinearity = match &self.nonlinearity {
                    Some(arg) => self.kind_of(arg, name)?,
                    None if self.linear_inputs.contains(name) => NonlinearityKind::Linear,
                    None => default,
                };
                Ok(InputSpec {
                    nb: nb[m],
                    nk: nk[m],
                    nonlinearity,
                })
            })
            .collect::<anyhow::Result<_>>()?;
        Ok(settings.with_inputs(inputs))
    }

    /// The nonlinearity `--nonlinearity` gives input `name` (every input named in a per-input list must
    /// be an input, and every input must be named).
    fn kind_of(&self, arg: &NonlinearityArg, name: &str) -> anyhow::Result<NonlinearityKind> {
        Ok(self.sized(self.kind_named(arg, name)?))
    }

    /// `kind` with `--breakpoints` and `--degree` applied.
    fn sized(&self, kind: NonlinearityKind) -> NonlinearityKind {
        let kind = match self.breakpoints {
            Some(k) => kind.with_breakpoints(k),
            None => kind,
        };
        match self.degree {
            Some(d) => kind.with_degree(d),
            None => kind,
        }
    }

    /// [`Args::kind_of`] before `--breakpoints` and `--degree`.
    fn kind_named(&self, arg: &NonlinearityArg, name: &str) -> anyhow::Result<NonlinearityKind> {
        let names = self.columns.csv_options(&self.memory).input_names();
        match arg {
            NonlinearityArg::All(kind) => Ok(*kind),
            NonlinearityArg::PerInput(list) => {
                if let Some((unknown, _)) = list.iter().find(|(n, _)| !names.contains(n)) {
                    anyhow::bail!(sysid::SysidError::setting(
                        sysid::Setting::Other("--nonlinearity"),
                        unknown,
                        &format!("names among the inputs of --u-col ({})", names.join(", "))
                    ));
                }
                match list.iter().find(|(n, _)| n == name) {
                    Some((_, kind)) => Ok(*kind),
                    None => anyhow::bail!(sysid::SysidError::setting(
                        sysid::Setting::Other("--nonlinearity"),
                        name,
                        "a kind for every input (NAME=KIND for each input of --u-col)"
                    )),
                }
            }
        }
    }
}

/// Runs `identify`: one record or several merged (`--merge`), one input or several, by any method;
/// several files without `--merge` are batch mode ([`super::identify_batch`]).
pub fn run(args: Args) -> anyhow::Result<()> {
    args.check_flags()?;
    if args.model == StructureArg::Narx {
        return super::identify_narx::run(&args);
    }
    let several_inputs = args.columns.u_col.contains(',');
    let batch = super::identify_batch::is_batch(&args.data);
    if args.stream == StreamMode::On && (several_inputs || args.merge || batch) {
        if batch {
            // A folder without a record is refused as such first, not for --stream (audit s30 L-2).
            super::identify_batch::expand(&args.data)?;
        }
        anyhow::bail!(refused_in_passes(
            "several inputs, --merge, several files and a folder are read in memory"
        ));
    }
    let settings = args.settings()?;
    // Refuse bad flags before reading anything, naming each input by its column.
    if several_inputs {
        let names: Vec<&str> = args.columns.u_col.split(',').map(str::trim).collect();
        settings.check_for(&names)?;
    } else {
        settings.check()?;
    }
    if batch && !args.merge {
        return super::identify_batch::run(args, &settings);
    }
    let Some(data_path) = args.data.first() else {
        anyhow::bail!("--data needs a file");
    };
    if !args.merge && !several_inputs && streaming(&args, &settings, data_path)? {
        return run_streamed(&args, &settings, data_path);
    }
    let (files, skipped_note) = if args.merge {
        let expanded = super::identify_batch::expand(&args.data)?;
        let note = expanded.skipped_note();
        (expanded.files, note)
    } else {
        (vec![data_path.clone()], None)
    };
    let mut inputs: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    inputs.extend(args.val.validation.as_deref());
    check_outputs(
        &[(&args.json, "--json"), (&args.save_model, "--save-model")],
        &inputs,
    )?;
    // A refusal for memory (the reader's, then the estimation's) offers `--stream on` where it would
    // read this record in passes (memory then does not grow with the record): one decision for both.
    let in_passes = (!args.merge && !several_inputs && could_stream(&args, &settings, data_path))
        .then_some(
            "--stream on, which reads the CSV record in passes (ARX by least squares: memory does \
             not grow with the record)",
        );
    let (records, val, mut notes) = read_records(&args, &files, in_passes)?;
    notes.splice(0..0, skipped_note);
    // The reader's notes are printed once, among the report's warnings ("data: …"; audit s18 L-6).
    let (estimation, op) = match records.as_slice() {
        [one] => {
            let (d, op) = detrend(one, args.detrend);
            (vec![d], op)
        }
        _ => (records.clone(), None),
    };
    // `identify` checks the same need again below.
    if let Err(e) = settings.check_memory(&estimation) {
        if let Some(how) = in_passes {
            anyhow::bail!(sysid::SysidError::Data(format!("{e}; or {how}")));
        }
        anyhow::bail!(e);
    }
    // An estimation that fails never reaches the report: the reader's notes are printed before the
    // error, as `validate` does.
    let said_notes = super::common::notes_before(&notes);
    let mut fit = identify(&estimation, &settings).map_err(&said_notes)?;
    if op.is_some() {
        // The range in the user's units, as the operating point is (identify saw deviations).
        fit.model = fit
            .model
            .with_operating_point(op)?
            .with_data_range(sysid::DataRange::of(&records))?;
    }
    // Metrics, residuals and warnings in the user's units: the model puts its operating point back.
    // After `--detrend linear` they are scored on the data the model was estimated from (the drift
    // removed, the means kept), as MATLAB's `compare(detrend(z, 1), m)`; the raw record's figures (what
    // `validate` gives on it) are reported beside them (audit s18 M-3).
    let (scored, drift) = match (args.detrend, records.as_slice()) {
        (Detrend::Linear, [one]) => {
            let (d, slope_u, slope_y) = sysid::detrend::drift_removed(one);
            let raw = sysid::metrics::metrics(&fit.model, one).ok();
            (
                vec![d],
                Some(DriftScoring {
                    slope_u,
                    slope_y,
                    raw,
                }),
            )
        }
        _ => (records.clone(), None),
    };
    let mut report =
        IdentifyReport::assemble(&fit, &settings, &scored, val.as_ref(), args.resid_lags)
            .map_err(&said_notes)?;
    // The reader's warnings (a resampled record...) are warnings about these numbers too.
    report.warnings.extend(super::common::data_notes(&notes));
    report
        .warnings
        .extend(in_sample_warnings(&args, &files, &records, val.as_ref()));
    report.warnings.extend(repeated_record_warnings(&records));
    if !report.warnings.is_empty() {
        report.warnings.extend(
            records
                .first()
                .and_then(super::common::swapped_columns_hint),
        );
    }
    let names: Vec<&str> = records.iter().map(|r| r.name()).collect();
    let n: usize = records.iter().map(Dataset::len).sum();
    let est_name = if records.len() > 1 {
        format!(
            "{} merged ({} records; no regression row spans two records)",
            names.join(" + "),
            records.len()
        )
    } else {
        names.join(" + ")
    };
    let val = val.as_ref().map(|v| (v.name(), v.len()));
    output(
        &args,
        &report,
        &fit.model,
        (&est_name, n),
        val,
        DataRemarks {
            notes: &notes,
            drift: drift.as_ref(),
        },
        &inputs,
    )
}

/// What the estimation figures of an `--detrend linear` identification are scored on: the record with
/// its drift removed and its means kept (the data the model was estimated from); the slopes removed
/// and, when the record was held in memory, the raw record's metrics (what `validate` reports on it).
#[derive(Debug, Clone, Default)]
struct DriftScoring {
    /// Slope β per sample removed from each input, in the record's order.
    slope_u: Vec<f64>,
    /// Slope β per sample removed from y.
    slope_y: f64,
    /// The model's metrics on the raw record (drift left in, operating point put back).
    raw: Option<sysid::metrics::Metrics>,
}

impl DriftScoring {
    /// The sentence of the text report.
    fn text(&self) -> String {
        use report::format::num;
        let mut s = String::from(
            "; the drift removed is not: the estimation figures above are scored on the detrended \
             record (the data the model was estimated from, its means kept",
        );
        if self.slope_y.is_finite() {
            s += &format!(
                "; drift per sample removed: y {}, u {}",
                num(self.slope_y),
                self.slope_u
                    .iter()
                    .map(|v| num(*v))
                    .collect::<Vec<_>>()
                    .join(", ")
            );
        }
        s += ")";
        if let Some(m) = &self.raw {
            let pct = |v: Option<f64>| v.map_or("n/a".to_string(), |v| format!("{} %", num(v)));
            s += &format!(
                "; on the raw record, drift left in, as `validate` scores it: fit {} (simulation), {} \
                 (sim., y0 meas.), {} (1-step pred.)",
                pct(m.fit_sim_percent),
                pct(m.fit_sim_measured_percent),
                pct(m.fit_pred_percent)
            );
        }
        s
    }

    /// The `detrend_scoring` object of `identify --json`.
    fn json(&self) -> serde_json::Value {
        let mut v = serde_json::json!({
            "scored_on": "detrended",
            "meaning": "estimation metrics and residuals are computed on the estimation record with its \
                        least-squares drift removed and its means kept: the data the model was estimated from",
        });
        if self.slope_y.is_finite() {
            v["drift_per_sample"] = serde_json::json!({"u": self.slope_u, "y": self.slope_y});
        }
        if let Some(m) = &self.raw {
            v["raw_record"] = serde_json::to_value(m).unwrap_or(serde_json::Value::Null);
        }
        v
    }
}

/// A warning for each merged record that holds the very samples of an earlier one (`--merge a.csv
/// a.csv`, a copied file), or a run of at least `MIN_SHARED_SAMPLES` of them (a record merged with a
/// file cut from it or containing it, audit s17 M-e): those samples then count twice, so the standard
/// deviations shrink and the fit statistics claim data the experiment never gave (audit s11).
fn repeated_record_warnings(records: &[Dataset]) -> Vec<String> {
    records
        .iter()
        .enumerate()
        .filter_map(|(j, r)| {
            if let Some(earlier) = records[..j].iter().find(|e| same_samples(e, r)) {
                return Some(format!(
                    "the merged record {} holds the same samples as {}: every sample counts twice, so \
                     the standard deviations are too small by √2 and the fit statistics claim data the \
                     experiment never gave (merge each record once)",
                    r.name(),
                    earlier.name()
                ));
            }
            records[..j].iter().find_map(|e| {
                let (i, k, n) = sysid_summary::shared_run(r, e)?;
                Some(format!(
                    "the merged record {} holds {n} consecutive samples of {} (its samples {i}..{} are \
                     the other's {k}..{}): they count twice, so the standard deviations are too small \
                     and the fit statistics claim data the experiment never gave (merge each stretch \
                     of the experiment once)",
                    r.name(),
                    e.name(),
                    i + n,
                    k + n
                ))
            })
        })
        .collect()
}

/// Warnings (audit s11 V1) when the validation record holds rows of an estimation file (the same file,
/// overlapping `--rows` and `--val-rows`) or the very samples of an estimation record: its fit is then
/// in-sample. `records` and `val` are the records read (none for the streamed path).
pub(super) fn in_sample_warnings(
    args: &Args,
    files: &[PathBuf],
    records: &[Dataset],
    val: Option<&Dataset>,
) -> Vec<String> {
    let opts = args.columns.csv_options(&args.memory);
    let Some(data) = files.first() else {
        return Vec::new();
    };
    if args.val.split.is_some() {
        return Vec::new(); // the validation rows follow the estimation rows
    }
    let Some((path, vopts)) = args.val.validation_source(data, &opts) else {
        return Vec::new();
    };
    let test = FileRows {
        file: path,
        rows: vopts.rows,
        columns: (&vopts.u_col, &vopts.y_col),
    };
    let mut w: Vec<String> = files
        .iter()
        .filter_map(|f| {
            let est = FileRows {
                file: f,
                rows: args.columns.rows,
                columns: (&opts.u_col, &opts.y_col),
            };
            shared_rows_warning("validation", test, "estimation", est)
        })
        .collect();
    if w.is_empty() {
        if let Some(v) = val {
            w.extend(
                records
                    .iter()
                    .find_map(|r| same_samples_warning("validation", v, r)),
            );
        }
    }
    w
}

/// The estimation records (one per file; `--split`/`--val-rows` of a single file apply) and the
/// validation record, with the reader's notes. `in_passes`: the `--stream on` a refusal for memory
/// may offer.
fn read_records(
    args: &Args,
    files: &[PathBuf],
    in_passes: Option<&str>,
) -> anyhow::Result<(Vec<Dataset>, Option<Dataset>, Vec<String>)> {
    let mut opts = args.columns.csv_options(&args.memory);
    opts.in_passes = in_passes.map(String::from);
    if let [one] = files {
        let r = args.val.records(one, &opts)?;
        return Ok((vec![r.est], r.val, r.notes));
    }
    if args.val.split.is_some() || args.detrend != Detrend::None {
        anyhow::bail!(
            "--merge cannot be combined with --detrend or --split; detrend or split the records first"
        );
    }
    if args.val.val_rows.is_some() && args.val.validation.is_none() {
        anyhow::bail!(
            "--merge with --val-rows needs --validation FILE (which of the merged records would the rows be of?)"
        );
    }
    let mut records = Vec::with_capacity(files.len());
    let mut notes = Vec::new();
    for f in files {
        let r = sysid::data::read_record(f, &opts)?;
        notes.extend(r.notes);
        records.push(r.data);
    }
    let est_ts = records.first().map(Dataset::ts);
    Ok((records, args.val.read(&opts, est_ts)?, notes))
}

/// What the report says about the estimation data beside the numbers: the reader's notes (a resampled
/// record...) and, after `--detrend linear`, what the estimation figures are scored on.
struct DataRemarks<'a> {
    notes: &'a [String],
    drift: Option<&'a DriftScoring>,
}

/// Prints the report of an identification (`est` and `val`: the records' names and lengths) and writes
/// `--json` and `--save-model`; the in-memory and the streaming paths share it.
fn output(
    args: &Args,
    report: &IdentifyReport,
    model: &sysid::Model,
    est: (&str, usize),
    val: Option<(&str, usize)>,
    remarks: DataRemarks<'_>,
    inputs: &[&Path],
) -> anyhow::Result<()> {
    let DataRemarks { notes, drift } = remarks;
    // One parseable document on standard output: the text goes to standard error when --json or
    // --save-model is `-` (check_outputs refuses both).
    let text = format!(
        "Data: {} ({} samples){}\n{}",
        est.0,
        est.1,
        val.map(|(name, len)| format!("; validation: {name} ({len} samples)"))
            .unwrap_or_default(),
        crate::text::identify_report(report)
    ) + &model
        .operating_point()
        .map(|o| {
            format!(
                "Detrended ({}): the model works around the operating point u0 = {}, y0 = {} (put back in \
                 its simulations and predictions){}\n",
                args.detrend,
                o.u.iter().map(|v| report::format::num(*v)).collect::<Vec<_>>().join(", "),
                report::format::num(o.y),
                drift.map(DriftScoring::text).unwrap_or_default()
            )
        })
        .unwrap_or_default();
    super::common::print_report(&text, &[args.json.as_deref(), args.save_model.as_deref()])?;
    let mut json = None;
    if args.json.is_some() {
        let mut text = report.to_json()?;
        if !notes.is_empty() || args.detrend != Detrend::None {
            // The reader's warnings and the detrending travel with the numbers they concern.
            let mut value: serde_json::Value = serde_json::from_str(&text)?;
            if let Some(obj) = value.as_object_mut() {
                obj.insert("detrend".into(), serde_json::json!(args.detrend));
                obj.insert("data_notes".into(), serde_json::json!(notes));
                if let Some(d) = drift {
                    obj.insert("detrend_scoring".into(), d.json());
                }
            }
            // `value` holds the report's mark already (`to_json`).
            text = serde_json::to_string_pretty(&value)? + "\n";
        }
        json = Some(text);
    }
    write_files(args, json.as_deref(), model, inputs, report, est.0)
}

/// Whether to read the record in passes (`--stream`, [`StreamMode::decide`]): ARX by least squares,
/// without `--split` or `--resample`.
fn streaming(args: &Args, settings: &Identification, data: &Path) -> anyhow::Result<bool> {
    // The words of a refusal: the structure and method when they are what cannot be streamed, else
    // the setting that needs the record in memory (audit s27 L-5: "expected an ARX model by least
    // squares" was said to a user who had asked for one).
    let model_supported = sysid::stream::unsupported(settings).is_none();
    args.stream
        .decide(data, why_not_stream(args, settings), |why| {
            if model_supported {
                refused_in_passes(why)
            } else {
                sysid::stream::refused(why)
            }
        })
}

/// The refusal of `--stream on` for a setting other than the model's structure and method (`why`).
fn refused_in_passes(why: &str) -> sysid::SysidError {
    sysid::SysidError::setting(
        sysid::Setting::Other("--stream"),
        "on",
        &format!("no --stream (or --stream off) with these settings: {why}"),
    )
}

/// Whether `--stream on` would read this record in passes, where a refusal for memory may offer it:
/// nothing against it ([`why_not_stream`]) and CSV files (the streaming reader reads CSV only).
fn could_stream(args: &Args, settings: &Identification, data: &Path) -> bool {
    why_not_stream(args, settings).is_none() && !sysid_core::data::mat::has_mat_name(data)
}

/// Why this identification cannot be read in passes, if it cannot: ARX by least squares only,
/// without `--split` or `--resample`, and a CSV validation record (audit s27 L-12: a large CSV with a
/// `.mat` validation record failed under the default `--stream auto`, advising to leave out a
/// `--stream` that was not given; now the default reads both in memory and says why).
fn why_not_stream(args: &Args, settings: &Identification) -> Option<String> {
    sysid::stream::unsupported(settings)
        .or_else(|| {
            args.val
                .validation
                .as_deref()
                .filter(|v| sysid_core::data::mat::has_mat_name(v))
                .map(|v| {
                    format!(
                        "the validation record {} is a MATLAB .mat file, which is read in memory",
                        v.display()
                    )
                })
        })
        .or_else(|| {
            args.val.split.is_some().then(|| {
                "--split needs the record's length before reading it; use --rows and --val-rows"
                    .into()
            })
        })
        .or_else(|| {
            args.columns
                .resample
                .is_some()
                .then(|| "--resample needs the whole record".into())
        })
}

/// `identify` with the records read in passes (`sysid::stream`): memory does not grow with the record.
fn run_streamed(args: &Args, settings: &Identification, data_path: &Path) -> anyhow::Result<()> {
    let inputs = checked_inputs(args, data_path)?;
    let opts = args.columns.csv_options(&args.memory);
    let mut est = CsvStream::open(data_path, &opts)?;
    let mut val = match args.val.validation_source(data_path, &opts) {
        Some((path, vopts)) => Some(CsvStream::open(path, &vopts)?),
        None => None,
    };
    let streamed = sysid_summary::stream::identify_report(
        &mut est,
        val.as_mut().map(|v| v as &mut dyn RecordSource),
        settings,
        args.detrend,
        args.resid_lags,
    );
    // The readers' notes (the record's, then the validation record's).
    let read_notes = |est: &CsvStream, val: &Option<CsvStream>| {
        let mut notes = est.notes().to_vec();
        notes.extend(val.iter().flat_map(|v| v.notes().iter().cloned()));
        notes
    };
    // A failing estimation prints them before its error, as in memory.
    let mut streamed =
        streamed.map_err(|e| super::common::notes_before(&read_notes(&est, &val))(e))?;
    // The validation record is sampled at the model's Ts, as the in-memory path requires (audit s27 M-3:
    // a record at 0.02 s was scored as if at 0.01 s).
    if let (Some(v), Some(vs)) = (&val, streamed.val_shape) {
        sysid::metrics::check_sampling_noted(
            RecordSource::name(v),
            vs.ts,
            streamed.shape.ts,
            v.notes(),
        )?;
    }
    let (fit, report) = &mut streamed.result;
    // After `--detrend linear`: the drift removed and the raw record's figures (a few more passes), as
    // the in-memory path reports them (audit s18 M-3).
    let drift = if args.detrend == Detrend::Linear {
        let (slope_u, slope_y) = sysid::stream::drift_slopes(&mut est)?;
        let raw = sysid::stream::record_metrics(&fit.model, &mut est, args.resid_lags)
            .ok()
            .map(|r| r.result.0);
        Some(DriftScoring {
            slope_u: vec![slope_u],
            slope_y,
            raw,
        })
    } else {
        None
    };
    // The readers' notes, as the in-memory path gives them (audit s27 M-2).
    let notes = read_notes(&est, &val);
    report.warnings.extend(super::common::data_notes(&notes));
    let mut in_sample = in_sample_warnings(args, &[data_path.to_path_buf()], &[], None);
    if in_sample.is_empty() {
        // A validation file that holds the estimation record's samples, found by the passes' checksums.
        if let Some((v, vs)) = val.as_ref().zip(streamed.val_shape) {
            let same = vs.rows == streamed.shape.rows
                && v.checksum().is_some()
                && v.checksum() == est.checksum();
            if same {
                in_sample.push(sysid_summary::same_samples_words(
                    "validation",
                    v.name(),
                    est.name(),
                ));
            }
        }
    }
    report.warnings.extend(in_sample);
    stream_note(
        est.name(),
        streamed.passes,
        streamed.shape.rows,
        args.stream,
    );
    if let Some((v, shape)) = val.as_ref().zip(streamed.val_shape) {
        stream_note(v.name(), streamed.val_passes, shape.rows, args.stream);
    }
    let val_desc = val
        .as_ref()
        .zip(streamed.val_shape)
        .map(|(v, s)| (v.name(), s.rows));
    output(
        args,
        report,
        &fit.model,
        (est.name(), streamed.shape.rows),
        val_desc,
        DataRemarks {
            notes: &notes,
            drift: drift.as_ref(),
        },
        &inputs,
    )
}

/// The input files (the record and the validation file) after checking that the outputs can be written
/// and name none of them.
pub(super) fn checked_inputs<'a>(
    args: &'a Args,
    data_path: &'a Path,
) -> anyhow::Result<Vec<&'a Path>> {
    let mut inputs: Vec<&Path> = vec![data_path];
    inputs.extend(args.val.validation.as_deref());
    check_outputs(
        &[(&args.json, "--json"), (&args.save_model, "--save-model")],
        &inputs,
    )?;
    Ok(inputs)
}

/// What a model file records of the identification that wrote it ([`sysid::model::Provenance`]): the
/// estimation `record` (its name with rows), the columns it was read from (by name when it has a
/// header), the free-run fit `fit` on it and the report's `warnings`. Linear and NARX models alike.
pub fn provenance(
    args: &Args,
    record: &str,
    fit: Option<f64>,
    warnings: &[String],
) -> sysid::model::Provenance {
    let named = !args.columns.no_header;
    sysid::model::Provenance {
        record: record.to_string(),
        u_columns: if named {
            args.columns
                .u_col
                .split(',')
                .map(|c| c.trim().to_string())
                .collect()
        } else {
            Vec::new()
        },
        y_column: named.then(|| args.columns.y_col.clone()),
        fit_estimation_percent: fit,
        warnings: warnings.to_vec(),
    }
}

/// Writes `--json` (its text `json`) and `--save-model`, if given, together; with `--strict` and
/// warnings neither file ([`super::common::write_outputs`]).
///
/// The model file records where the model came from (`record`, the columns, the fit and the report's
/// warnings: [`sysid::model::Provenance`]), so that the commands that load it repeat the warnings
/// (audit s20 M-3).
fn write_files(
    args: &Args,
    json: Option<&str>,
    model: &sysid::Model,
    inputs: &[&Path],
    report: &IdentifyReport,
    record: &str,
) -> anyhow::Result<()> {
    let warnings = report.warnings.len();
    let saved = match &args.save_model {
        Some(_) => {
            let provenance = provenance(
                args,
                record,
                sysid::trust::guarded_fit(&report.metrics.estimation),
                &report.warnings,
            );
            Some(sysid::model_file::to_json(
                &model.clone().with_provenance(Some(provenance)),
            )?)
        }
        None => None,
    };
    let mut outputs: Vec<(&Path, &[u8], &str)> = Vec::new();
    if let (Some(path), Some(text)) = (&args.json, json) {
        outputs.push((path, text.as_bytes(), "--json"));
    }
    if let (Some(path), Some(text)) = (&args.save_model, &saved) {
        outputs.push((path, text.as_bytes(), "--save-model"));
    }
    super::common::write_outputs(&outputs, inputs, args.strict, warnings)
}
