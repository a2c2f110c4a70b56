//! Set-point profiles r(t) in mm: the paper's fixed set-point and unfixed set-points (a staircase, or a
//! sampled-and-held record from a CSV file).
//!
//! Specification strings (command-line `--profile`):
//!
//! | spec                         | profile                                                            |
//! |------------------------------|--------------------------------------------------------------------|
//! | `fixed:50` or `50`           | r(t) = 50 mm for all t                                             |
//! | `staircase:20,60,100,40@3`   | 20 mm for 0 <= t < 3 s, 60 mm for 3 <= t < 6 s, ..., the last held |
//! | `file:PATH.csv`              | columns `t` (s) and `r` (mm), sample-and-hold between rows         |

use std::path::{Path, PathBuf};

use serde::Serialize;

use crate::ControlError;

/// Tolerance (relative, in units of the hold time or of Ts) applied when locating t on a grid, so that
/// t = k Ts computed in floating point lands on the intended side of a switching instant.
const GRID_EPS: f64 = 1e-9;

/// A set-point profile r(t) in mm.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "kebab-case")]
pub enum Profile {
    /// The paper's fixed set-point: r(t) = `setpoint_mm`.
    Fixed {
        /// r: the set-point in mm.
        setpoint_mm: f64,
    },
    /// Unfixed set-point: each level in turn for `hold_s` seconds; the last level is held after the end.
    Staircase {
        /// The successive set-points in mm.
        levels_mm: Vec<f64>,
        /// How long each level is held, in s (> 0).
        hold_s: f64,
    },
    /// Unfixed set-point from a file: r(t) = r_i for t_i <= t < t_(i+1) (sample-and-hold); r_0 before t_0,
    /// the last r after the last t.
    Samples {
        /// The file it came from (for reports).
        path: PathBuf,
        /// t_i in s, strictly increasing.
        t_s: Vec<f64>,
        /// r_i in mm.
        r_mm: Vec<f64>,
        /// Line and column (1-based) of the last row's t in the file, for errors about the run it sets
        /// (`None`: not read from a file, e.g. an array given to the Python package).
        #[serde(skip)]
        last_t_at: Option<(usize, usize)>,
    },
}

impl Profile {
    /// True when the profile is made of held steps (a fixed set-point or a staircase), each of which is
    /// judged against the paper's acceptance ([`crate::LoopFacts::judge_steps`]); a profile read from
    /// samples may change r every sample.
    pub fn has_held_steps(&self) -> bool {
        matches!(self, Profile::Fixed { .. } | Profile::Staircase { .. })
    }

    /// Parses a specification string (see the module documentation); `file:` specs read the file.
    ///
    /// ```
    /// use control::Profile;
    /// let p = Profile::parse("staircase:20,60,100,40@3").unwrap();
    /// assert_eq!(p.r_at(0.0), 20.0);
    /// assert_eq!(p.r_at(3.0), 60.0);
    /// assert_eq!(p.r_at(100.0), 40.0);
    /// assert_eq!(p.natural_duration_s(), Some(12.0));
    /// ```
    pub fn parse(spec: &str) -> Result<Profile, ControlError> {
        let err = |message: String| ControlError::Profile {
            spec: spec.to_string(),
            message,
        };
        let s = spec.trim();
        let (kind, rest) = match s.split_once(':') {
            Some((k, r)) => (k.trim(), r.trim()),
            None => ("fixed", s),
        };
        match kind {
            "fixed" => {
                let setpoint_mm = parse_mm(rest).map_err(|m| err(format!("{m}; expected `fixed:MM`, e.g. `fixed:50`")))?;
                Ok(Profile::Fixed { setpoint_mm })
            }
            "staircase" => {
                let expected = "expected `staircase:L1,L2,...@HOLD_S`, e.g. `staircase:20,60,100,40@3` (levels in mm, hold in s)";
                let (levels, hold) = rest.rsplit_once('@').ok_or_else(|| err(format!("no `@HOLD_S`; {expected}")))?;
                let hold_s: f64 = hold
                    .trim()
                    .parse()
                    .map_err(|_| err(format!("hold time `{}` is not a number; {expected}", hold.trim())))?;
                if !(hold_s.is_finite() && hold_s > 0.0) {
                    return Err(err(format!(
                        "hold time {} s must be finite and > 0; {expected}",
                        sysid_core::format::Shortest(hold_s)
                    )));
                }
                let mut levels_mm = Vec::new();
                for (i, l) in levels.split(',').enumerate() {
                    let v = parse_mm(l).map_err(|m| err(format!("level {}: {m}; {expected}", i + 1)))?;
                    levels_mm.push(v);
                }
                Ok(Profile::Staircase { levels_mm, hold_s })
            }
            "file" => {
                if rest.is_empty() {
                    return Err(err("no file name; expected `file:PATH.csv` with columns t,r".into()));
                }
                Profile::from_csv_file(Path::new(rest)).map_err(|e| match e {
                    ControlError::Profile { message, .. } => err(message),
                    other => other,
                })
            }
            other => Err(err(format!("unknown profile kind `{other}`; expected `fixed:MM`, `staircase:L1,L2,...@HOLD_S` or `file:PATH.csv`"))),
        }
    }

    /// Reads a profile file: CSV with a header naming columns `t` (s) and `r` (mm) (also accepted: `t_s`,
    /// `r_mm`; other columns are ignored), at least one row, finite values, strictly increasing t.
    pub fn from_csv_file(path: &Path) -> Result<Profile, ControlError> {
        let file = path.display().to_string();
        let err = |message: String| ControlError::Profile {
            spec: format!("file:{}", sysid_core::format::visible(&file)),
            message,
        };
        // Every CSV reader's rules and bounds (file size, line length, header, cells; audit s22 H-B2).
        let core = |e: sysid_core::SysidError| match e {
            sysid_core::SysidError::Io { path, source } => ControlError::Io { path, source },
            other => err(other.to_string()),
        };
        let bytes =
            sysid_core::data::bounded::read_data_file(path, "a profile file").map_err(core)?;
        let table = sysid_core::data::read_table(&bytes, &file).map_err(core)?;
        let find = |alts: &[&str]| {
            table
                .headers
                .iter()
                .position(|n| alts.contains(&n.to_ascii_lowercase().as_str()))
        };
        let (it, ir) = match (find(&["t", "t_s"]), find(&["r", "r_mm"])) {
            (Some(a), Some(b)) => (a, b),
            _ => {
                let header = table.headers.join(",");
                return Err(err(format!(
                    "{file}:1: header `{}` has no `t` and `r` columns; expected a header like `t,r` (t in s, r in mm)",
                    sysid_core::format::visible(&header)
                )));
            }
        };
        let t_s = table.numbers(it).map_err(core)?;
        let r_mm = table.numbers(ir).map_err(core)?;
        for (k, w) in t_s.windows(2).enumerate() {
            if w[1] <= w[0] {
                return Err(err(format!(
                    "{file}:{}:{}: t = {} s does not increase (previous row t = {} s); expected strictly increasing times",
                    table.line_of(k + 1),
                    it + 1,
                    sysid_core::format::Shortest(w[1]),
                    sysid_core::format::Shortest(w[0])
                )));
            }
        }
        if t_s.is_empty() {
            return Err(err(format!(
                "{file}: no data rows after the header; expected at least one row t,r"
            )));
        }
        Ok(Profile::Samples {
            path: path.to_path_buf(),
            last_t_at: Some((table.line_of(t_s.len().saturating_sub(1)), it + 1)),
            t_s,
            r_mm,
        })
    }

    /// Checks a profile built in code (parsed ones are already valid): finite values, at least one level
    /// or row, hold time > 0, equal-length strictly increasing file rows.
    pub fn validate(&self) -> Result<(), ControlError> {
        let err = |message: &str| {
            Err(ControlError::Profile {
                spec: self.spec(),
                message: message.to_string(),
            })
        };
        match self {
            Profile::Fixed { setpoint_mm } if !setpoint_mm.is_finite() => {
                err("the set-point must be finite")
            }
            Profile::Staircase { levels_mm, hold_s } => {
                if levels_mm.is_empty() || levels_mm.iter().any(|v| !v.is_finite()) {
                    err("expected at least one level, all finite")
                } else if !(hold_s.is_finite() && *hold_s > 0.0) {
                    err("expected a finite hold time > 0 s")
                } else {
                    Ok(())
                }
            }
            Profile::Samples { t_s, r_mm, .. } => {
                if t_s.is_empty() || t_s.len() != r_mm.len() {
                    err("expected at least one row and as many times as set-points")
                } else if t_s.iter().chain(r_mm).any(|v| !v.is_finite())
                    || t_s.windows(2).any(|w| w[1] <= w[0])
                {
                    err("expected finite values and strictly increasing times")
                } else {
                    Ok(())
                }
            }
            _ => Ok(()),
        }
    }

    /// Refuses a staircase that holds each level for less than one sampling period `ts` (s): r(t) is
    /// read at t = k Ts, so levels would be skipped without a word (audit s16 L1: `staircase:50,60,70@0.001`
    /// at Ts = 0.01 s never applied 60).
    pub fn check_sampling(&self, ts: f64) -> Result<(), ControlError> {
        match self {
            Profile::Staircase { hold_s, .. } if *hold_s < ts * (1.0 - GRID_EPS) => {
                Err(ControlError::Profile {
                    spec: self.spec(),
                    message: format!(
                        "each level is held {} s, less than the sampling period Ts = {} s, so some \
                         levels would never be applied; hold each level at least one sample",
                        sysid_core::format::Shortest(*hold_s),
                        sysid_core::format::Shortest(ts)
                    ),
                })
            }
            _ => Ok(()),
        }
    }

    /// The set-point r(t) in mm at time `t_s` (s from the start of the run).
    pub fn r_at(&self, t_s: f64) -> f64 {
        match self {
            Profile::Fixed { setpoint_mm } => *setpoint_mm,
            Profile::Staircase { levels_mm, hold_s } => {
                let Some(&last) = levels_mm.last() else {
                    return 0.0;
                };
                let idx = (t_s / hold_s + GRID_EPS).floor();
                if idx < 0.0 {
                    levels_mm[0]
                } else if idx >= levels_mm.len() as f64 {
                    last
                } else {
                    levels_mm[idx as usize]
                }
            }
            Profile::Samples { t_s: ts, r_mm, .. } => {
                // Number of t_i <= t (with tolerance), minus one, is the row in force.
                let tol = GRID_EPS * (1.0 + t_s.abs());
                let n = ts.partition_point(|&ti| ti <= t_s + tol);
                r_mm[n.saturating_sub(1)]
            }
        }
    }

    /// The profile's own length in s: levels × hold for a staircase, the last t for a file; `None` for a
    /// fixed set-point (the caller chooses).
    pub fn natural_duration_s(&self) -> Option<f64> {
        match self {
            Profile::Fixed { .. } => None,
            Profile::Staircase { levels_mm, hold_s } => Some(levels_mm.len() as f64 * hold_s),
            Profile::Samples { t_s, .. } => t_s.last().copied(),
        }
    }

    /// The run's length when no duration is given, [`Profile::natural_duration_s`], refused when it
    /// would take [`crate::closed_loop::MAX_SAMPLES`] samples of `ts` (s) or more, with the error
    /// naming where the length came from: the profile file's last time (file:line:column) or the
    /// staircase's levels and hold (audit s28 L-7: a last time of 1e308 s blamed `--duration`, which
    /// the user had not typed). `None` for a fixed set-point, which has no length of its own.
    pub fn natural_duration_checked(&self, ts: f64) -> Result<Option<f64>, ControlError> {
        use sysid_core::format::Shortest;
        let Some(d) = self.natural_duration_s() else {
            return Ok(None);
        };
        let max = crate::closed_loop::MAX_SAMPLES;
        if crate::closed_loop::run_samples(d, ts).is_some() {
            return Ok(Some(d));
        }
        let limit = format!(
            "a run may have at most {max} samples of Ts = {} s ({} s)",
            Shortest(ts),
            Shortest(max as f64 * ts)
        );
        let message = match self {
            Profile::Samples {
                path, last_t_at, ..
            } => format!(
                "{}{}: the last time t = {} s sets the run's length, but {limit}; expected times up to \
                 that, or pass --duration to end the run earlier",
                sysid_core::format::visible(&path.display().to_string()),
                last_t_at.map_or(String::new(), |(line, col)| format!(":{line}:{col}")),
                Shortest(d)
            ),
            Profile::Staircase { levels_mm, hold_s } => format!(
                "{} levels held {} s each make a run of {} s, but {limit}; expected a shorter hold, or \
                 pass --duration to end the run earlier",
                levels_mm.len(),
                Shortest(*hold_s),
                Shortest(d)
            ),
            // Has no natural duration (returned above); kept whole for the match.
            Profile::Fixed { .. } => return Ok(Some(d)),
        };
        Err(ControlError::Profile {
            spec: self.spec(),
            message,
        })
    }

    /// The profile written back as a specification (`fixed:50`, `staircase:20,60@3`, `file:PATH`),
    /// numbers in [`sysid_core::format::Shortest`] form, for errors about a profile built or parsed.
    fn spec(&self) -> String {
        use sysid_core::format::Shortest;
        match self {
            Profile::Fixed { setpoint_mm } => format!("fixed:{}", Shortest(*setpoint_mm)),
            Profile::Staircase { levels_mm, hold_s } => {
                let l: Vec<String> = levels_mm.iter().map(|v| Shortest(*v).to_string()).collect();
                format!("staircase:{}@{}", l.join(","), Shortest(*hold_s))
            }
            Profile::Samples { path, .. } => {
                format!(
                    "file:{}",
                    sysid_core::format::visible(&path.display().to_string())
                )
            }
        }
    }

    /// A warning when a run of `duration_s` ends at (or before) the instant the profile's last row
    /// changes the set-point: that set-point is then applied for at most one sample and never judged
    /// (audit s11: rows `0,50` and `2,100` ran 2 s and dropped r = 100 silently).
    pub fn last_row_warning(&self, duration_s: f64) -> Option<String> {
        let Profile::Samples {
            path, t_s, r_mm, ..
        } = self
        else {
            return None;
        };
        let (&t_last, &r_last) = (t_s.last()?, r_mm.last()?);
        let r_before = *r_mm.get(r_mm.len().checked_sub(2)?)?;
        (r_last != r_before && duration_s <= t_last).then(|| {
            use sysid_core::format::Shortest;
            format!(
                "the last row of {} changes the set-point to r = {} mm at t = {} s, where the run ends \
                 ({} s): it is never held, so no step to it is judged; pass --duration to hold it",
                path.display(),
                Shortest(r_last),
                Shortest(t_last),
                Shortest(duration_s)
            )
        })
    }

    /// A short description for summaries ("fixed 50 mm", "staircase 20, 60 mm, 3 s each", "file x.csv").
    pub fn describe(&self) -> String {
        self.describe_in("mm")
    }

    /// [`Profile::describe`] with the set-points in `unit` (a model plant's output units).
    pub fn describe_in(&self, unit: &str) -> String {
        use sysid_core::format::Shortest;
        match self {
            Profile::Fixed { setpoint_mm } => {
                format!("fixed set-point {} {unit}", Shortest(*setpoint_mm))
            }
            Profile::Staircase { levels_mm, hold_s } => {
                let l: Vec<String> = levels_mm.iter().map(|v| Shortest(*v).to_string()).collect();
                format!(
                    "staircase {} {unit}, {} s each",
                    l.join(", "),
                    Shortest(*hold_s)
                )
            }
            Profile::Samples { path, t_s, .. } => {
                format!("set-points from {} ({} rows)", path.display(), t_s.len())
            }
        }
    }
}

fn parse_mm(s: &str) -> Result<f64, String> {
    let s = s.trim();
    if s.is_empty() {
        return Err("empty value".into());
    }
    let v: f64 = s
        .parse()
        .map_err(|_| format!("`{s}` is not a number of mm"))?;
    if !v.is_finite() {
        return Err(format!("`{s}` is not finite"));
    }
    Ok(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_profile_is_constant() {
        // r(t) = 50 for every t; a bare number means fixed.
        for spec in ["fixed:50", "50", " fixed: 50 "] {
            let p = Profile::parse(spec).unwrap();
            assert_eq!(p, Profile::Fixed { setpoint_mm: 50.0 });
            assert_eq!(p.r_at(0.0), 50.0);
            assert_eq!(p.r_at(1e6), 50.0);
        }
    }

    #[test]
    fn staircase_switches_at_multiples_of_the_hold_time() {
        // r(t) = level[floor(t / hold)], exactly at k Ts = 3 s with Ts = 0.01 (300 * 0.01 in floating point).
        let p = Profile::parse("staircase:20,60,100,40@3").unwrap();
        assert_eq!(p.r_at(2.99), 20.0);
        assert_eq!(p.r_at(300.0 * 0.01), 60.0);
        assert_eq!(p.r_at(599.0 * 0.01), 60.0);
        // Held exactly one sample: accepted; held less: refused, naming Ts (audit s16 L1).
        let one = Profile::parse("staircase:50,60,70@0.01").unwrap();
        assert!(one.check_sampling(0.01).is_ok());
        let short = Profile::parse("staircase:50,60,70@0.001").unwrap();
        let e = short.check_sampling(0.01).unwrap_err().to_string();
        assert!(
            e.contains("less than the sampling period Ts = 0.01 s"),
            "{e}"
        );
        assert_eq!(p.r_at(600.0 * 0.01), 100.0);
        assert_eq!(p.r_at(11.99), 40.0);
        assert_eq!(p.r_at(50.0), 40.0);
        assert_eq!(p.natural_duration_s(), Some(12.0));
    }

    #[test]
    fn a_run_too_long_is_blamed_on_the_profile_that_sets_it() {
        // A loop runs at most MAX_SAMPLES = 1e7 samples: 1e5 s at Ts = 0.01 s. Without --duration the
        // profile's own length is checked against that, and the error names where the length came
        // from (audit s28 L-7: a file's last time of 1e308 s blamed a --duration nobody typed).
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        // The last row is on line 4 (a blank line before it), its t in column 2.
        std::fs::write(&path, "r,t\n10,0\n\n20,1e308\n").unwrap();
        let p = Profile::parse(&format!("file:{}", path.display())).unwrap();
        let e = p.natural_duration_checked(0.01).unwrap_err().to_string();
        assert!(
            e.contains("r.csv:4:2: the last time t = 1e308 s")
                && e.contains("at most 10000000 samples of Ts = 0.01 s (100000 s)"),
            "{e}"
        );
        assert!(e.len() < 400, "printed digit by digit: {e}");
        // Just inside the bound (99999 s: 9999900 samples) the length is the last time.
        std::fs::write(&path, "t,r\n0,10\n99999,20\n").unwrap();
        let q = Profile::parse(&format!("file:{}", path.display())).unwrap();
        assert_eq!(q.natural_duration_checked(0.01).unwrap(), Some(99999.0));
        // A staircase: 2 levels of 1e300 s; its error names the levels and the hold.
        let s = Profile::parse("staircase:10,20@1e300").unwrap();
        let e = s.natural_duration_checked(0.01).unwrap_err().to_string();
        assert!(
            e.contains("`staircase:10,20@1e300`") && e.contains("2 levels held 1e300 s each"),
            "{e}"
        );
        assert_eq!(
            Profile::parse("staircase:10,20@3")
                .unwrap()
                .natural_duration_checked(0.01)
                .unwrap(),
            Some(6.0)
        );
        // A fixed set-point has no length of its own.
        assert_eq!(
            Profile::parse("fixed:50")
                .unwrap()
                .natural_duration_checked(0.01)
                .unwrap(),
            None
        );
        // A hold shorter than Ts is printed as typed (audit s28 L-3: 1e-300 s printed 300 digits).
        let tiny = Profile::parse("staircase:10,20@1e-300").unwrap();
        let e = tiny.check_sampling(0.01).unwrap_err().to_string();
        assert!(e.contains("each level is held 1e-300 s"), "{e}");
    }

    #[test]
    fn bad_specs_name_the_spec_and_what_was_expected() {
        // Each malformed spec is rejected with its text and the expected form in the message.
        for (spec, needle) in [
            ("staircase:20,60", "@HOLD_S"),
            ("staircase:20,x@3", "`x` is not a number"),
            ("staircase:20,60@0", "must be finite and > 0"),
            ("staircase:20,,60@1", "empty value"),
            ("ramp:1", "unknown profile kind"),
            ("fixed:nan", "not finite"),
            ("file:", "no file name"),
        ] {
            let msg = Profile::parse(spec).unwrap_err().to_string();
            assert!(msg.contains(spec), "{msg}");
            assert!(msg.contains(needle), "{msg}");
        }
    }

    #[test]
    fn file_profile_samples_and_holds() {
        // r(t) = r_i for t_i <= t < t_(i+1); r_0 before t_0; the last r after the last t.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        std::fs::write(&path, "t,r\n0.5,10\n1.0,-5\n2,30\n").unwrap();
        let p = Profile::parse(&format!("file:{}", path.display())).unwrap();
        assert_eq!(p.r_at(0.0), 10.0);
        assert_eq!(p.r_at(0.5), 10.0);
        assert_eq!(p.r_at(0.99), 10.0);
        assert_eq!(p.r_at(100.0 * 0.01), -5.0);
        assert_eq!(p.r_at(3.0), 30.0);
        assert_eq!(p.natural_duration_s(), Some(2.0));
        // Its last row changes r (−5 → 30) at t = 2 s: a run of 2 s never holds it, one of 3 s does.
        let w = p.last_row_warning(2.0).expect("a warning");
        assert!(
            w.contains("r = 30 mm at t = 2 s") && w.contains("--duration"),
            "{w}"
        );
        assert!(p.last_row_warning(3.0).is_none());
        // A last row that repeats the set-point (a sampled trajectory) changes nothing.
        std::fs::write(&path, "t,r\n0,10\n1,20\n2,20\n").unwrap();
        let q = Profile::parse(&format!("file:{}", path.display())).unwrap();
        assert!(q.last_row_warning(2.0).is_none());
    }

    #[test]
    fn file_errors_give_line_and_column() {
        // Row 3 (line 3), column 2 holds a non-number; times must increase; the header needs t and r.
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("r.csv");
        let check = |content: &str, needle: &str| {
            std::fs::write(&path, content).unwrap();
            let msg = Profile::parse(&format!("file:{}", path.display()))
                .unwrap_err()
                .to_string();
            assert!(msg.contains(needle), "{msg} lacks {needle}");
        };
        check(
            "t,r\n0,1\n1,abc\n",
            "r.csv:3:2: 'abc' in column 'r' is not a number",
        );
        check("t,r\n0,1\n0,2\n", "r.csv:3:1: t = 0 s does not increase");
        check("time,pos\n0,1\n", "r.csv:1: header");
        check("t,r\n", "no data rows");
        check(
            "t,r\n0\n",
            "r.csv:2:2: the row has only 1 of the header's 2 fields",
        );
        // Audit s22 H-B2: a line longer than every CSV reader's bound (1 MiB) is refused at its line.
        check(
            &"1".repeat((1 << 20) + 1),
            "r.csv:1:1048577: the line is longer than 1048576 bytes",
        );
        check("t,r\n0,inf\n", "not a finite number");
        let missing = dir.path().join("nope.csv");
        assert!(Profile::parse(&format!("file:{}", missing.display()))
            .unwrap_err()
            .to_string()
            .contains("nope.csv"));
    }
}
