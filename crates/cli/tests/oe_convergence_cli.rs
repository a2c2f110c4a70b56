//! Output-error searches that said "converged" where a plain Levenberg–Marquardt still lowers the cost
//! a lot (issue 22, audit finding 2), through the binary on the measured records of `../shared/data`
//! (each test skips, saying so, when the folder is absent). The expectations are computed here, by an
//! independent free-run simulation of the saved model (its initial outputs estimated by this file's own
//! least squares) and finite differences of that simulation — never copied from the program's output.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;

use std::path::{Path, PathBuf};

use serde_json::Value;

fn data_dir() -> Option<PathBuf> {
    ipa_testdata::shared_data()
}

/// Runs `ipa-sysid ARGS --save-model … --json …` in `dir` (it must succeed): the JSON document and the
/// saved model.
fn identify(dir: &Path, args: &[&str]) -> (Value, Value) {
    let tmp = tempfile::tempdir().unwrap();
    let model = tmp.path().join("m.json");
    let mut all = args.to_vec();
    all.extend(["--save-model", model.to_str().unwrap()]);
    let doc = common::run_json(dir, &all);
    let saved = serde_json::from_str(&std::fs::read_to_string(&model).unwrap()).unwrap();
    (doc, saved)
}

/// Columns `u` and `y` of a CSV file with a header row.
fn columns(path: &Path, u: &str, y: &str) -> (Vec<f64>, Vec<f64>) {
    let mut r = csv::Reader::from_path(path).unwrap();
    let h = r.headers().unwrap().clone();
    let iu = h.iter().position(|c| c.trim() == u).unwrap();
    let iy = h.iter().position(|c| c.trim() == y).unwrap();
    let (mut us, mut ys) = (Vec::new(), Vec::new());
    for rec in r.records() {
        let rec = rec.unwrap();
        us.push(rec[iu].trim().parse().unwrap());
        ys.push(rec[iy].trim().parse().unwrap());
    }
    (us, ys)
}

/// A deadzone-Hammerstein model written as θ = [a1..a_na, b2..b_nb, (c), b_l, b_r, m_l, m_r] (b1 = 1).
struct Shape {
    na: usize,
    nb: usize,
    nk: usize,
    offset: bool,
}

impl Shape {
    fn k0(&self) -> usize {
        self.na.max(self.nk + self.nb - 1)
    }

    /// θ of the saved model file.
    fn theta(model: &Value) -> (Self, Vec<f64>) {
        let m = &model["model"];
        let f = |v: &Value| v.as_f64().unwrap();
        let a: Vec<f64> = m["a"].as_array().unwrap().iter().map(f).collect();
        let b: Vec<f64> = m["b"].as_array().unwrap().iter().map(f).collect();
        assert_eq!(b[0], 1.0, "b1 = 1 normalisation");
        let shape = Shape {
            na: a.len(),
            nb: b.len(),
            nk: m["nk"].as_u64().unwrap() as usize,
            offset: !m["offset"].is_null(),
        };
        let mut theta = a;
        theta.extend(&b[1..]);
        if shape.offset {
            theta.push(f(&m["offset"]));
        }
        let dz = &m["deadzone"];
        theta.extend(["b_l", "b_r", "m_l", "m_r"].iter().map(|k| f(&dz[k])));
        (shape, theta)
    }

    /// Free run: ŷ(k) = η_k for k < k0, ŷ(k) = −Σ a_i ŷ(k−i) + Σ b_j x(k−nk−j+1) + c after, x the
    /// deadzone of u (paper eq. 1: the right branch for u ≥ b_r, the left for u ≤ b_l, else 0).
    /// `inputs = false` drops B and c (the response to the initial outputs alone).
    fn simulate(&self, theta: &[f64], u: &[f64], eta: &[f64], inputs: bool) -> Vec<f64> {
        let (na, nb, nk) = (self.na, self.nb, self.nk);
        let a = &theta[..na];
        let mut b = vec![1.0];
        b.extend(&theta[na..na + nb - 1]);
        let mut i = na + nb - 1;
        let c = if self.offset {
            i += 1;
            theta[i - 1]
        } else {
            0.0
        };
        let (bl, br, ml, mr) = (theta[i], theta[i + 1], theta[i + 2], theta[i + 3]);
        let x: Vec<f64> = u
            .iter()
            .map(|&v| {
                if v >= br {
                    mr * (v - br)
                } else if v <= bl {
                    ml * (v - bl)
                } else {
                    0.0
                }
            })
            .collect();
        let mut yh = eta.to_vec();
        for k in self.k0()..u.len() {
            let mut v = 0.0;
            for (i, ai) in a.iter().enumerate() {
                v -= ai * yh[k - 1 - i];
            }
            if inputs {
                v += c;
                for (j, bj) in b.iter().enumerate() {
                    v += bj * x[k - nk - j];
                }
            }
            yh.push(v);
        }
        yh
    }

    /// The initial outputs η minimising Σ_k (y(k) − ŷ(k))² over every sample (ŷ is affine in η), by
    /// the normal equations.
    fn initial_outputs(&self, theta: &[f64], u: &[f64], y: &[f64]) -> Vec<f64> {
        let k0 = self.k0();
        let s0 = self.simulate(theta, u, &vec![0.0; k0], true);
        let cols: Vec<Vec<f64>> = (0..k0)
            .map(|j| {
                let mut e = vec![0.0; k0];
                e[j] = 1.0;
                self.simulate(theta, u, &e, false)
            })
            .collect();
        let d: Vec<f64> = y.iter().zip(&s0).map(|(a, b)| a - b).collect();
        least_squares(&cols, &d)
    }

    /// y − ŷ over every sample for θ extended by the initial outputs.
    fn residuals(&self, full: &[f64], u: &[f64], y: &[f64]) -> Vec<f64> {
        let n = full.len() - self.k0();
        let yh = self.simulate(&full[..n], u, &full[n..], true);
        y.iter().zip(&yh).map(|(a, b)| a - b).collect()
    }
}

/// The least-squares solution of Σ_j cols[j] w_j ≈ d (normal equations with the columns scaled to unit
/// norm, Cholesky).
fn least_squares(cols: &[Vec<f64>], d: &[f64]) -> Vec<f64> {
    let p = cols.len();
    let dot = |a: &[f64], b: &[f64]| a.iter().zip(b).map(|(x, y)| x * y).sum::<f64>();
    let s: Vec<f64> = cols.iter().map(|c| dot(c, c).sqrt().max(1e-300)).collect();
    let mut g = vec![vec![0.0; p]; p];
    let mut rhs = vec![0.0; p];
    for i in 0..p {
        for j in 0..p {
            g[i][j] = dot(&cols[i], &cols[j]) / (s[i] * s[j]);
        }
        rhs[i] = dot(&cols[i], d) / s[i];
    }
    // Cholesky G = L Lᵀ, then L z = rhs, Lᵀ w = z.
    let mut l = vec![vec![0.0; p]; p];
    for i in 0..p {
        for j in 0..=i {
            let sum: f64 = (0..j).map(|k| l[i][k] * l[j][k]).sum();
            if i == j {
                l[i][i] = (g[i][i] - sum).max(1e-14).sqrt();
            } else {
                l[i][j] = (g[i][j] - sum) / l[j][j];
            }
        }
    }
    let mut z = vec![0.0; p];
    for i in 0..p {
        z[i] = (rhs[i] - (0..i).map(|k| l[i][k] * z[k]).sum::<f64>()) / l[i][i];
    }
    let mut w = vec![0.0; p];
    for i in (0..p).rev() {
        w[i] = (z[i] - (i + 1..p).map(|k| l[k][i] * w[k]).sum::<f64>()) / l[i][i];
    }
    w.iter().zip(&s).map(|(w, s)| w / s).collect()
}

/// 100 (1 − ‖y − ŷ‖ / ‖y − ȳ‖) over the samples from k0 on (docs/estimators.md).
fn fit(y: &[f64], yh: &[f64], k0: usize) -> f64 {
    let (y, yh) = (&y[k0..], &yh[k0..]);
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let e: f64 = y.iter().zip(yh).map(|(a, b)| (a - b) * (a - b)).sum();
    let d: f64 = y.iter().map(|a| (a - mean) * (a - mean)).sum();
    100.0 * (1.0 - (e / d).sqrt())
}

// The audit's robot arm Hammerstein OE (4, 4, 1) on rows 0..512 ended "converged" at a deadzone with
// crossed breakpoints (b_l = 0.753 > b_r = 0.037: a jump at b_r the search crept towards), fit 49 % /
// 45 %, where scipy's Levenberg–Marquardt from that end reached 81 % / 80 % with b_l = 0.034,
// b_r = 0.037. The search now restarts from ordered breakpoints: the model is physical and fits both the
// estimation rows and the test rows 512..1024 far better, by this file's own simulation.
#[test]
fn robot_arm_hammerstein_output_error_does_not_lose_the_good_model() {
    let Some(dir) = data_dir() else { return };
    let (doc, model) = identify(
        &dir,
        &[
            "identify",
            "--data",
            "robot_arm_flexible/robot_arm.csv",
            "--ts",
            "1",
            "--structure",
            "hammerstein",
            "--method",
            "oe",
            "--na",
            "4",
            "--nb",
            "4",
            "--nk",
            "1",
            "--rows",
            "0..512",
            "--val-rows",
            "512..1024",
        ],
    );
    let (shape, theta) = Shape::theta(&model);
    let i = theta.len() - 4;
    assert!(
        theta[i] <= theta[i + 1],
        "deadzone not physical: b_l = {} > b_r = {}",
        theta[i],
        theta[i + 1]
    );
    let (u, y) = columns(&dir.join("robot_arm_flexible/robot_arm.csv"), "u", "y");
    let k0 = shape.k0();
    for (rows, name) in [(0..512, "estimation"), (512..1024, "validation")] {
        let (u, y) = (&u[rows.clone()], &y[rows]);
        let eta = shape.initial_outputs(&theta, u, y);
        let estimated = fit(y, &shape.simulate(&theta, u, &eta, true), k0);
        let measured = fit(y, &shape.simulate(&theta, u, &y[..k0], true), k0);
        let m = &doc["metrics"][name];
        let reported = m["fit_sim_measured_percent"].as_f64().unwrap();
        assert!(
            (measured - reported).abs() < 0.1,
            "{name}: measured-start fit {measured} here, {reported} reported"
        );
        // Before: 49.3 / 45.3 % (estimated initial outputs), 38.4 / 33.7 % (measured).
        assert!(
            estimated >= 70.0 && measured >= 60.0,
            "{name}: fit {estimated} % (estimated initial outputs), {measured} % (measured)"
        );
    }
}

// Gas furnace Hammerstein OE (2, 2, 3) --offset: the search used to say "converged (relative change of
// the cost below tolerance)" while scipy's Levenberg–Marquardt lowered the cost by 6.5 %. Whether the
// end point is stationary is judged here independently: the Gauss–Newton model of the criterion (this
// file's simulation, finite-difference Jacobian over every parameter the criterion is smooth in — all
// but the breakpoints b_l, b_r, whose input levels make kinks — and the initial outputs) predicts a
// relative decrease rᵀJ (JᵀJ)⁻¹ Jᵀr / rᵀr; above 2 % the point is no minimum and the tool must not
// claim convergence, below 0.5 % it must (the old end predicted 13 % and claimed convergence).
#[test]
fn output_error_does_not_claim_convergence_away_from_a_stationary_point() {
    let Some(dir) = data_dir() else { return };
    let (doc, model) = identify(
        &dir,
        &[
            "identify",
            "--data",
            "gas_furnace_box_jenkins/gas_furnace.csv",
            "--ts",
            "9",
            "--u-col",
            "InputGasRate",
            "--y-col",
            "CO2",
            "--structure",
            "hammerstein",
            "--method",
            "oe",
            "--na",
            "2",
            "--nb",
            "2",
            "--nk",
            "3",
            "--offset",
        ],
    );
    let (shape, theta) = Shape::theta(&model);
    let (u, y) = columns(
        &dir.join("gas_furnace_box_jenkins/gas_furnace.csv"),
        "InputGasRate",
        "CO2",
    );
    let mut full = theta.clone();
    full.extend(shape.initial_outputs(&theta, &u, &y));
    let r = shape.residuals(&full, &u, &y);
    let cost: f64 = r.iter().map(|v| v * v).sum();
    // θ = [a1, a2, b2, c, b_l, b_r, m_l, m_r, η…]: b_l and b_r follow a, b2.. and c.
    let bl = shape.na + shape.nb - 1 + usize::from(shape.offset);
    let smooth = (0..full.len()).filter(|&q| q != bl && q != bl + 1);
    let jac: Vec<Vec<f64>> = smooth
        .map(|q| {
            let h = 1e-6 * (1.0 + full[q].abs());
            let (mut up, mut down) = (full.clone(), full.clone());
            up[q] += h;
            down[q] -= h;
            let (ru, rd) = (shape.residuals(&up, &u, &y), shape.residuals(&down, &u, &y));
            ru.iter()
                .zip(&rd)
                .map(|(a, b)| (a - b) / (2.0 * h))
                .collect()
        })
        .collect();
    let w = least_squares(&jac, &r);
    let fitted: Vec<f64> = (0..r.len())
        .map(|k| jac.iter().zip(&w).map(|(c, w)| c[k] * w).sum())
        .collect();
    let left: f64 = r.iter().zip(&fitted).map(|(a, b)| (a - b) * (a - b)).sum();
    let predicted = (cost - left) / cost;
    eprintln!("Gauss-Newton predicted relative decrease at the end point: {predicted:.4}");
    let converged = doc["estimation"]["converged"].as_bool().unwrap();
    let note = doc["estimation"]["note"].as_str().unwrap();
    assert!(
        !(0.005..=0.02).contains(&predicted),
        "inconclusive: the Gauss-Newton model predicts {predicted}"
    );
    if predicted > 0.02 {
        assert!(
            !converged && note.contains("not converged"),
            "predicted decrease {predicted} but converged: {note}"
        );
        let w = common::warnings(&doc);
        assert!(w.iter().any(|w| w.contains("not converged")), "{w:?}");
    } else {
        assert!(converged, "stationary (predicted {predicted}) but: {note}");
    }
}

// Audit s14 L-q: when the output-error refinement is rejected and the least-squares start is returned,
// the text header and the JSON `estimation` block say so (`returned`), while `method`, `iterations` and
// `converged` still describe the search that ran. Checked independently: the returned model's
// parameters are those of `--method ls` on the same record and orders.
#[test]
fn a_rejected_output_error_refinement_says_the_least_squares_start_was_returned() {
    let Some(dir) = data_dir() else { return };
    let common_args = [
        "identify",
        "--data",
        "robot_arm_flexible/robot_arm.csv",
        "--ts",
        "1",
        "--rows",
        "0..512",
        "--na",
        "8",
        "--nb",
        "7",
        "--nk",
        "1",
        "--structure",
        "arx",
        "--offset",
    ];
    let mut oe_args = common_args.to_vec();
    oe_args.extend(["--method", "oe"]);
    let (oe, oe_model) = identify(&dir, &oe_args);
    let fell_back = common::warnings(&oe)
        .iter()
        .any(|w| w.starts_with("fallback used: the least-squares start"));
    let returned = oe["estimation"]["returned"].as_str();
    assert_eq!(oe["estimation"]["method"], "oe");
    if !fell_back {
        assert!(
            returned.is_none(),
            "no fallback, yet returned = {returned:?}"
        );
        eprintln!("SKIPPED: the output-error refinement was kept on this record; the fallback report was not checked");
        return;
    }
    assert_eq!(
        returned,
        Some("the least-squares start instead of the output-error refinement")
    );
    let mut ls_args = common_args.to_vec();
    ls_args.extend(["--method", "ls"]);
    let (ls, _) = identify(&dir, &ls_args);
    let values = |d: &Value| -> Vec<f64> {
        d["parameters"]
            .as_array()
            .unwrap()
            .iter()
            .map(|p| p["value"].as_f64().unwrap())
            .collect()
    };
    let (a, b) = (values(&oe), values(&ls));
    assert_eq!(a.len(), b.len());
    for (x, y) in a.iter().zip(&b) {
        assert!(
            (x - y).abs() <= 1e-9 * (1.0 + y.abs()),
            "returned {x} vs least squares {y}"
        );
    }
    let _ = oe_model;
    let out = common::bin()
        .current_dir(&dir)
        .args(&oe_args)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("returned: the least-squares start instead of the output-error refinement"),
        "{text}"
    );
}
