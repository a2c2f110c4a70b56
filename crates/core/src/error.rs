//! The error types of the core: [`SysidError`] for data, models and settings (also used by the
//! estimators of crate `sysid`), and [`PlantError`] for the [`Plant`](crate::Plant) trait.

use std::path::PathBuf;

/// A setting of the library that a caller chose (the command line maps each to its flag, e.g.
/// [`Setting::Na`] to `--na`; the Python package to its keyword argument).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Setting {
    /// na: order of A(q).
    Na,
    /// nb: number of coefficients of B(q).
    Nb,
    /// nk: input delay in samples.
    Nk,
    /// Ts: sampling period in s.
    Ts,
    /// The input column of a data file.
    UCol,
    /// The output column of a data file.
    YCol,
    /// The time column of a data file.
    TCol,
    /// ρ: RLS forgetting factor.
    Forgetting,
    /// P(0) = p0 · I: RLS initial covariance scale.
    P0,
    /// Number of RLS passes over the data.
    Passes,
    /// Bound T on tr P of the trace windup guard.
    MaxTrace,
    /// Number of instrumental-variable stages.
    IvStages,
    /// Iteration cap of an iterative estimator.
    MaxIterations,
    /// Relative tolerance of the key-term iteration.
    Tolerance,
    /// Reading a data file without a header row (its columns named by position).
    NoHeader,
    /// The memory budget of one estimation, in GiB ([`crate::ls::MemoryBudget`]).
    MaxMemory,
    /// K: the first sample (0-based row of the record) at which a validation's figures are scored
    /// ([`crate::metrics::first_scored`]).
    ScoreFrom,
    /// Any other setting, by the name the caller uses (an application's own options).
    Other(&'static str),
}

impl Setting {
    /// The name used in the library's own messages (`na`, `forgetting`, ...), which is also the keyword
    /// of the Python package.
    pub fn name(&self) -> &'static str {
        match self {
            Setting::Na => "na",
            Setting::Nb => "nb",
            Setting::Nk => "nk",
            Setting::Ts => "ts",
            Setting::UCol => "u_col",
            Setting::YCol => "y_col",
            Setting::TCol => "t_col",
            Setting::Forgetting => "forgetting",
            Setting::P0 => "p0",
            Setting::Passes => "passes",
            Setting::MaxTrace => "max_trace",
            Setting::IvStages => "iv_stages",
            Setting::MaxIterations => "max_iterations",
            Setting::Tolerance => "tolerance",
            Setting::NoHeader => "no_header",
            Setting::MaxMemory => "max_memory_gb",
            Setting::ScoreFrom => "score_from",
            Setting::Other(name) => name,
        }
    }
}

impl Setting {
    /// The command-line flag of the setting (`--na`, `--forgetting`, ...); [`Setting::Other`] is already
    /// named as the caller wants it. The command line and the Python package both render errors with
    /// these, so that their messages are the same.
    pub fn flag(&self) -> &'static str {
        match self {
            Setting::Na => "--na",
            Setting::Nb => "--nb",
            Setting::Nk => "--nk",
            Setting::Ts => "--ts",
            Setting::UCol => "--u-col",
            Setting::YCol => "--y-col",
            Setting::TCol => "--t-col",
            Setting::Forgetting => "--forgetting",
            Setting::P0 => "--p0",
            Setting::Passes => "--passes",
            Setting::MaxTrace => "--max-trace",
            Setting::IvStages => "--iv-stages",
            Setting::MaxIterations => "--max-iterations",
            Setting::Tolerance => "tolerance",
            Setting::NoHeader => "--no-header",
            Setting::MaxMemory => "--max-memory",
            Setting::ScoreFrom => "--score-from",
            Setting::Other(name) => name,
        }
    }
}

impl std::fmt::Display for Setting {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Why a column named by a setting is not in a file's header, beyond its absence.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum ColumnHint {
    /// Every header cell is a number: the file has no header row.
    NoHeader,
    /// As [`ColumnHint::NoHeader`], read by a reader that needs a header row (`track`, which has no
    /// `--no-header`: audit s37 L-3, it advised that flag).
    HeaderNeeded,
    /// The file was read without a header row (its columns named 1..=n by position) and the column was
    /// named otherwise.
    ByPosition(usize),
    /// A header name equal to the requested one but for case.
    Case(String),
    /// A header name that holds the requested one among words separated by spaces (`t u y`): the file
    /// separates its columns by spaces, which the reader does not (a space is part of a name, as in
    /// `y [mm]`).
    Spaces(String),
}

/// Where the name of a column that a file lacks came from, so that its message says who chose it
/// (audit s22 L-N3: "chosen by --u-col" when no --u-col was typed).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColumnOrigin {
    /// The setting's default name (`u`, `y`, `t`).
    Default,
    /// A name the user gave (a flag's value, a Python argument).
    Given,
    /// The column a model file recorded as its identification's (`validate` reads it when --u-col /
    /// --y-col are not typed).
    ModelFile,
}

impl ColumnOrigin {
    /// The origin of `column` chosen by `setting`: [`ColumnOrigin::Default`] when it is the setting's
    /// default name (`u` for --u-col, `y` for --y-col, `t` for --t-col), [`ColumnOrigin::Given`]
    /// otherwise (a typed `--u-col u` is the default name, and is called so).
    pub fn of(setting: Setting, column: &str) -> Self {
        let default = match setting {
            Setting::UCol => "u",
            Setting::YCol => "y",
            Setting::TCol => "t",
            _ => return ColumnOrigin::Given,
        };
        if column == default {
            ColumnOrigin::Default
        } else {
            ColumnOrigin::Given
        }
    }
}

/// Everything that can go wrong with data, models and settings. Messages name the file, line and column
/// (1-based) or the setting at fault, and what was expected.
#[derive(Debug)]
pub enum SysidError {
    /// A data or model file could not be read or written.
    Io {
        /// The file concerned.
        path: PathBuf,
        /// The operating system's error.
        source: std::io::Error,
    },
    /// A file's content is malformed at a known place.
    Parse {
        /// The file (or `<stdin>` / `<memory>`).
        file: String,
        /// 1-based line number.
        line: usize,
        /// 1-based column number (field index for CSV).
        column: usize,
        /// What was found and what was expected.
        message: String,
    },
    /// A file is malformed as a whole (too few rows, wrong schema...).
    File {
        /// The file concerned.
        file: String,
        /// What is wrong and what was expected.
        message: String,
    },
    /// A column chosen by a setting is not in a file's header.
    MissingColumn {
        /// The file concerned.
        file: String,
        /// The column asked for.
        column: String,
        /// Which setting chose it.
        setting: Setting,
        /// The header's column names.
        header: Vec<String>,
        /// What probably went wrong, when it can be told (boxed: the error stays small).
        hint: Option<Box<ColumnHint>>,
        /// Where the column's name came from.
        origin: ColumnOrigin,
    },
    /// A variable chosen by a setting is not in a MAT-file.
    MissingVariable {
        /// The file concerned.
        file: String,
        /// The variable asked for.
        variable: String,
        /// Which setting chose it.
        setting: Setting,
        /// The names of the variables the file holds.
        variables: Vec<String>,
    },
    /// A setting is outside its valid range.
    Setting {
        /// The setting at fault.
        setting: Setting,
        /// The value given.
        value: String,
        /// What is accepted.
        expected: String,
    },
    /// Two settings chose the same data column.
    SameColumn {
        /// The setting that chose the column second.
        setting: Setting,
        /// The setting that chose it first.
        other: Setting,
        /// The column.
        column: String,
    },
    /// The data cannot support the requested estimate (too short, not persistently exciting...).
    Data(String),
    /// A numerical failure: non-finite values, loss of positive definiteness, singular problem.
    Numerical(String),
    /// The caller asked the computation to stop ([`crate::Stop`]: Ctrl-C in Python) before it
    /// finished; there is no result.
    Cancelled,
}

/// The most characters of one word (a run without white space) or one line that an error message echoes
/// ([`clip`]).
pub const MAX_ECHO_CHARS: usize = 80;

/// The most characters [`clip`] keeps of a word holding a path separator (Linux's PATH_MAX).
pub const MAX_PATH_CHARS: usize = 4096;

/// `text` with every word (a run without white space) longer than [`MAX_ECHO_CHARS`] cut to that many
/// characters and `…` (a word holding a path separator only beyond [`MAX_PATH_CHARS`]: file names are
/// echoed whole), and every line cut to 25 × [`MAX_ECHO_CHARS`] + [`MAX_PATH_CHARS`] (a long
/// message of many short words is kept whole): the one cap on what an error
/// message echoes of its input (a 200 kB TOML line, a 309-digit number, a 1 MB cell). The command line
/// applies it to every error it prints.
pub fn clip(text: &str) -> String {
    clip_to(text, MAX_ECHO_CHARS, MAX_PATH_CHARS)
}

/// `s` cut to its first `n` characters and `…`; `None` when it has at most `n` (the cut of [`clip`]
/// and of the cell and column names messages echo).
pub fn cut_chars(s: &str, n: usize) -> Option<String> {
    s.char_indices()
        .nth(n)
        .map(|(i, _)| format!("{}…", &s[..i]))
}

/// [`clip`] with words cut to `max` characters, words holding a path separator to `path_max` (lines
/// to 25 × `max` + `path_max`).
fn clip_to(text: &str, max: usize, path_max: usize) -> String {
    let cut = |s: &str, n: usize| -> Option<String> { cut_chars(s, n) };
    let mut out = String::with_capacity(text.len().min(8 * max));
    for (i, line) in text.split('\n').enumerate() {
        if i > 0 {
            out.push('\n');
        }
        let mut line_out = String::new();
        let mut rest = line;
        while !rest.is_empty() {
            let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
            let (word, after) = rest.split_at(end);
            // A word holding a path separator may be a file's path, which is never cut below the
            // longest path a system takes (4096 bytes on Linux).
            let cap = if word.contains(std::path::MAIN_SEPARATOR) {
                max.max(path_max)
            } else {
                max
            };
            line_out.push_str(&cut(word, cap).unwrap_or_else(|| word.to_string()));
            let space = after.len() - after.trim_start().len();
            line_out.push_str(&after[..space]);
            rest = &after[space..];
        }
        out.push_str(&cut(&line_out, 25 * max + path_max).unwrap_or(line_out));
    }
    out
}

impl SysidError {
    /// The message, with each [`Setting`] named by `name` (the library's own names in `Display`; the
    /// command line passes its flag names, so that its messages say `--na` where this says `na`).
    pub fn render(&self, name: &dyn Fn(Setting) -> String) -> String {
        match self {
            SysidError::Io { path, source } => format!("{}: {source}", path.display()),
            SysidError::Parse {
                file,
                line,
                column,
                message,
            } => format!("{file}:{line}:{column}: {message}"),
            SysidError::File { file, message } => format!("{file}: {message}"),
            SysidError::MissingColumn {
                file,
                column,
                setting,
                header,
                hint,
                origin,
            } => {
                let flag = name(*setting);
                let chosen = match origin {
                    ColumnOrigin::Given => format!("chosen by {flag}"),
                    ColumnOrigin::Default => {
                        format!("the default of {flag}; name yours with {flag} NAME")
                    }
                    ColumnOrigin::ModelFile => format!(
                        "the model file's column, read because {flag} was not given; name yours \
                         with {flag} NAME"
                    ),
                };
                let hint = match hint.as_deref() {
                    None => String::new(),
                    Some(ColumnHint::NoHeader) => format!(
                        " (the first row holds numbers: the file has no header row; pass {} and name \
                         the columns by position ({flag} 2), or add a header such as t,u,y)",
                        name(Setting::NoHeader)
                    ),
                    Some(ColumnHint::HeaderNeeded) => " (the first row holds numbers: the file has \
                         no header row, which this command needs to name its columns; add one such as \
                         t,u,y naming every column, or give the file to identify or validate, which \
                         read it with --no-header)"
                        .to_string(),
                    Some(ColumnHint::ByPosition(n)) => format!(
                        " (with {} the columns are named by their position, 1 to {n}: give {flag} a \
                         column number)",
                        name(Setting::NoHeader)
                    ),
                    Some(ColumnHint::Case(h)) => {
                        format!(" (names are case-sensitive: did you mean {flag} {h}?)")
                    }
                    Some(ColumnHint::Spaces(h)) => format!(
                        " (the header's name '{}' holds spaces: spaces do not separate columns, they \
                         may be part of a name such as 'y [mm]'; separate the columns with commas, ';' \
                         or tabs)",
                        crate::data::shorten(h)
                    ),
                };
                // A damaged header can hold huge or countless names: echo a bounded part of it.
                const SHOWN: usize = 50;
                let mut names: Vec<String> = header
                    .iter()
                    .take(SHOWN)
                    .map(|h| crate::data::shorten(h))
                    .collect();
                if header.len() > SHOWN {
                    names.push(format!("... ({} columns in all)", header.len()));
                }
                format!(
                    "{file}: no column named '{}' ({chosen}); the header has: {}{hint}",
                    crate::data::shorten(column),
                    names.join(", ")
                )
            }
            SysidError::MissingVariable {
                file,
                variable,
                setting,
                variables,
            } => {
                // A damaged file can hold countless names: echo a bounded part of them.
                const SHOWN: usize = 50;
                let mut names: Vec<String> = variables
                    .iter()
                    .take(SHOWN)
                    .map(|v| crate::data::shorten(v))
                    .collect();
                if variables.len() > SHOWN {
                    names.push(format!("... ({} variables in all)", variables.len()));
                }
                format!(
                    "{file}: no variable named '{}' (chosen by {}); the MAT-file holds: {}",
                    crate::data::shorten(variable),
                    name(*setting),
                    names.join(", ")
                )
            }
            SysidError::Setting {
                setting,
                value,
                expected,
            } => format!("invalid setting {} = {value}: {expected}", name(*setting)),
            SysidError::SameColumn {
                setting,
                other,
                column,
            } => format!(
                "invalid setting {} = {column}: a column different from {} ({} and {} cannot be the same column)",
                name(*setting),
                name(*other),
                other_symbol(*other),
                other_symbol(*setting),
            ),
            SysidError::Data(m) => m.clone(),
            SysidError::Numerical(m) => format!("numerical failure: {m}"),
            SysidError::Cancelled => {
                "stopped at the caller's request before the end (no result)".to_string()
            }
        }
    }
}

/// The signal a column setting chooses (u, y, t), for messages.
fn other_symbol(s: Setting) -> &'static str {
    match s {
        Setting::UCol => "u",
        Setting::YCol => "y",
        Setting::TCol => "t",
        _ => "the two",
    }
}

impl SysidError {
    /// The message with each [`Setting`] named by its command-line flag ([`Setting::flag`]): what the
    /// command line prints after `error: ` and what the Python package raises.
    pub fn render_flags(&self) -> String {
        self.render(&|s| s.flag().to_string())
    }
}

impl std::fmt::Display for SysidError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.render(&|s| s.name().to_string()))
    }
}

impl std::error::Error for SysidError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            SysidError::Io { source, .. } => Some(source),
            _ => None,
        }
    }
}

impl SysidError {
    /// True for failures of the numerics (exit code 1) rather than of the input (exit code 2).
    pub fn is_numerical(&self) -> bool {
        matches!(self, SysidError::Numerical(_))
    }

    /// Shorthand for a [`SysidError::Setting`].
    pub fn setting(setting: Setting, value: impl ToString, expected: &str) -> Self {
        SysidError::Setting {
            setting,
            value: shown_value(value),
            expected: expected.to_string(),
        }
    }

    /// The message of an error about the record named `record`, without that name where the error
    /// opens with it — a [`SysidError::File`] of that record, or the `record: ` that
    /// [`SysidError::context`] puts before a [`SysidError::Data`] or [`SysidError::Numerical`] — for a
    /// caller whose own words already name the record (a fleet window: "actuator 7, window 3 (t
    /// 60–79.99 s): …"). Every other error is rendered whole ([`SysidError::render`]).
    pub fn render_within(&self, record: &str, name: &dyn Fn(Setting) -> String) -> String {
        match self {
            SysidError::File { file, message } if file == record => message.clone(),
            SysidError::Data(m) | SysidError::Numerical(m) => m
                .strip_prefix(record)
                .and_then(|rest| rest.strip_prefix(": "))
                .unwrap_or(m)
                .to_string(),
            other => other.render(name),
        }
    }

    /// The error as it should reach a user of the record named `record`: [`SysidError::context`] with
    /// that name unless the message names it already (a callee named it, perhaps inside a slice name
    /// such as `rec.csv[0..200]`). What `estimate::identify` and the streamed identification (audit s35
    /// M-3: "least squares produced a non-finite estimate" came without any file under `--stream on`)
    /// give for a failure on a record.
    pub fn naming(self, record: &str) -> Self {
        if self.to_string().contains(record) {
            self
        } else {
            self.context(record)
        }
    }

    /// Prefixes a [`SysidError::Data`] or [`SysidError::Numerical`] message with `context` (for
    /// example the data set's name); other variants already say where they come from. A message that
    /// already starts with `context: ` is kept as it is (the callee named the record itself: audit s17
    /// L-c, `validate` printed "rec.csv[998..1000]: rec.csv[998..1000]: …").
    pub fn context(self, context: &str) -> Self {
        let prefix = |m: String| {
            if m.strip_prefix(context)
                .is_some_and(|rest| rest.starts_with(": "))
            {
                m
            } else {
                format!("{context}: {m}")
            }
        };
        match self {
            SysidError::Data(m) => SysidError::Data(prefix(m)),
            SysidError::Numerical(m) => SysidError::Numerical(prefix(m)),
            other => other,
        }
    }
}

/// Failure of a [`Plant`](crate::Plant) step.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlantError {
    /// The plant's state became non-finite (an unstable identified model, a diverging integration).
    #[error("{0}")]
    Diverged(String),
    /// The caller asked the run to stop ([`crate::Stop`], polled by a [`crate::plant::Stoppable`]
    /// plant: Ctrl-C in Python) before it finished; there is no result.
    #[error("stopped at the caller's request before the end (no result)")]
    Cancelled,
}

impl From<PlantError> for SysidError {
    fn from(e: PlantError) -> Self {
        match e {
            PlantError::Diverged(m) => SysidError::Numerical(m),
            PlantError::Cancelled => SysidError::Cancelled,
        }
    }
}

/// A setting's value as an error message shows it: as given, except a number, which is shown as
/// [`crate::format::Shortest`] prints it (exponent form below 1e-5 and from 1e16: `5e-7`, not
/// `0.0000005`; `1.7e308`, not 309 digits; docs/plant.md), the rule of Ts and times in messages (audit
/// s35b L-12). A whole number of at most 24 digits (a count: `--samples 10000000000`, u64::MAX, a
/// Python integer of 2^70) is shown with its digits, unless it has more than 16 (beyond the whole
/// numbers an f64 holds exactly) and is the text an f64 prints (its shortest digits padded with zeros:
/// `--forgetting=123456789012345678901` read as 123456789012345680000, digits the user did not type;
/// audit s37 L-5): that one is shown in exponent form, `1.2345678901234568e20`.
pub fn shown_value(value: impl ToString) -> String {
    let text = value.to_string();
    let digits = text.strip_prefix('-').unwrap_or(&text);
    if !digits.is_empty() && digits.len() <= 24 && digits.bytes().all(|b| b.is_ascii_digit()) {
        let padded_f64 = digits.len() > 16
            && text
                .parse::<f64>()
                .is_ok_and(|x| x.is_finite() && x.to_string() == text);
        if !padded_f64 {
            return text;
        }
    }
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() => crate::format::shortest(x),
        _ => text,
    }
}

#[cfg(test)]
mod shown_value_tests {
    use super::shown_value;

    #[test]
    fn numbers_are_shown_as_shortest_prints_them_and_counts_with_their_digits() {
        assert_eq!(shown_value(1e300), "1e300");
        assert_eq!(shown_value(1.7e308), "1.7e308");
        assert_eq!(shown_value(-2.5e-30), "-2.5e-30");
        assert_eq!(shown_value(0.5), "0.5");
        assert_eq!(shown_value(2e-9), "2e-9");
        assert_eq!(shown_value(5e-7), "5e-7");
        assert_eq!(shown_value(1e-5), "0.00001");
        assert_eq!(shown_value(2e9), "2000000000");
        assert_eq!(shown_value(1e25), "1e25");
        assert_eq!(shown_value(1u128 << 70), "1180591620717411303424");
        assert_eq!(shown_value(f64::NAN), "NaN");
        assert_eq!(shown_value("ipa"), "ipa");
        assert_eq!(shown_value("1e-7"), "1e-7");
        assert_eq!(shown_value(u64::MAX), u64::MAX.to_string());
        assert_eq!(shown_value(-12), "-12");
        // Audit s37 L-5: an f64 beyond 2^53 prints its shortest digits padded with zeros.
        assert_eq!(
            shown_value("123456789012345678901".parse::<f64>().unwrap()),
            "1.2345678901234568e20"
        );
        assert_eq!(shown_value(1e21), "1e21");
        assert_eq!(shown_value(-1e17), "-1e17");
        assert_eq!(shown_value(9007199254740992.0), "9007199254740992");
    }
}

#[cfg(test)]
mod context_tests {
    use super::SysidError;

    #[test]
    fn a_context_is_added_once() {
        let e = SysidError::Data("2 samples are not enough".into()).context("rec.csv[998..1000]");
        assert_eq!(
            e.to_string(),
            SysidError::Data("rec.csv[998..1000]: 2 samples are not enough".into()).to_string()
        );
        // Named already by the callee: not named again.
        let shown = e.to_string();
        let again = e.context("rec.csv[998..1000]");
        assert_eq!(again.to_string(), shown);
        // Another record's name, or a name that is only a prefix of the first word, is still added.
        let other = SysidError::Numerical("rec.csv: overflow".into()).context("rec");
        assert_eq!(
            other.to_string(),
            SysidError::Numerical("rec: rec.csv: overflow".into()).to_string()
        );
    }

    // A failure is named by its record once: added where the message does not name it, kept where it
    // does (also inside a slice name), and another record's name does not stand for it.
    #[test]
    fn naming_adds_the_record_only_where_the_message_lacks_it() {
        let bare = SysidError::Numerical("non-finite estimate".into()).naming("big.csv");
        assert_eq!(
            bare.to_string(),
            "numerical failure: big.csv: non-finite estimate"
        );
        let sliced = SysidError::Numerical("big.csv[0..200]: non-finite estimate".into());
        assert_eq!(
            sliced.naming("big.csv").to_string(),
            "numerical failure: big.csv[0..200]: non-finite estimate"
        );
        let other = SysidError::Numerical("val.csv: overflow".into()).naming("big.csv");
        assert_eq!(
            other.to_string(),
            "numerical failure: big.csv: val.csv: overflow"
        );
    }
}
