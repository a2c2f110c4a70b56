//! Parameterisations of a model structure: the names of the parameters, which are free, and the maps
//! between a parameter vector and a [`Model`].
//!
//! Two layouts exist (docs/paper.md, key-term separation):
//! - **key-term** θ (what the linear regression estimates): ARX θ = [a1..a_na, b1..b_nb, (c)];
//!   Hammerstein θ = [m_r, m_r b_r, m_l, m_l b_l, a1..a_na, b2..b_nb, (c)] with b1 = 1;
//! - **physical** (what the output-error search moves and what is reported): ARX as above;
//!   Hammerstein [b_l, b_r, m_l, m_r, a1..a_na, b2..b_nb, (c)].

use nalgebra::DMatrix;
use serde::{Deserialize, Deserializer, Serialize, Serializer};

use crate::{Deadzone, Model, ModelKind, Structure, SysidError};

/// The name of one model parameter (paper symbols).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ParamName {
    /// b_l: left deadzone breakpoint (counts).
    BL,
    /// b_r: right deadzone breakpoint (counts).
    BR,
    /// m_l: left deadzone slope.
    ML,
    /// m_r: right deadzone slope.
    MR,
    /// m_r b_r: key-term product.
    MrBr,
    /// m_l b_l: key-term product.
    MlBl,
    /// a_i (1-based).
    A(usize),
    /// b_j (1-based).
    B(usize),
    /// c: constant offset of the linear block.
    C,
    /// s_l: lower saturation breakpoint.
    SL,
    /// s_r: upper saturation breakpoint.
    SR,
    /// m: slope of a saturation.
    M,
    /// m s_l: key-term product of a saturation.
    MSl,
    /// m s_r: key-term product of a saturation.
    MSr,
    /// m_l s_l: key-term product of a deadzone with saturation.
    MlSl,
    /// m_r s_r: key-term product of a deadzone with saturation.
    MrSr,
    /// p_i: breakpoint i of a piecewise-linear map (1-based).
    Knot(usize),
    /// s_i: slope of segment i of a piecewise-linear map (0-based: s0 below p1).
    Slope(usize),
    /// d_i = s_i − s_{i−1}: slope change at p_i (key term, 1-based).
    Kink(usize),
    /// d_i p_i: key-term product (1-based).
    KinkKnot(usize),
    /// g_i: coefficient of u^i of a polynomial (1-based).
    Poly(usize),
}

impl std::fmt::Display for ParamName {
    /// The paper's symbol; honours width and alignment (`{:<6}`).
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let text = match self {
            ParamName::BL => "b_l".to_string(),
            ParamName::BR => "b_r".to_string(),
            ParamName::ML => "m_l".to_string(),
            ParamName::MR => "m_r".to_string(),
            ParamName::MrBr => "m_r*b_r".to_string(),
            ParamName::MlBl => "m_l*b_l".to_string(),
            ParamName::A(i) => format!("a{i}"),
            ParamName::B(j) => format!("b{j}"),
            ParamName::C => "c".to_string(),
            ParamName::SL => "s_l".to_string(),
            ParamName::SR => "s_r".to_string(),
            ParamName::M => "m".to_string(),
            ParamName::MSl => "m*s_l".to_string(),
            ParamName::MSr => "m*s_r".to_string(),
            ParamName::MlSl => "m_l*s_l".to_string(),
            ParamName::MrSr => "m_r*s_r".to_string(),
            ParamName::Knot(i) => format!("p{i}"),
            ParamName::Slope(i) => format!("s{i}"),
            ParamName::Kink(i) => format!("d{i}"),
            ParamName::KinkKnot(i) => format!("d{i}*p{i}"),
            ParamName::Poly(i) => format!("g{i}"),
        };
        f.pad(&text)
    }
}

impl PartialEq<&str> for ParamName {
    /// Compares with the paper's symbol (`ParamName::BL == "b_l"`).
    fn eq(&self, other: &&str) -> bool {
        other.parse::<ParamName>().is_ok_and(|n| n == *self)
    }
}

impl Serialize for ParamName {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for ParamName {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

impl std::str::FromStr for ParamName {
    type Err = SysidError;
    fn from_str(t: &str) -> Result<Self, SysidError> {
        let index = |rest: &str| rest.parse::<usize>().ok().filter(|&i| i >= 1);
        Ok(match t {
            "b_l" => ParamName::BL,
            "b_r" => ParamName::BR,
            "m_l" => ParamName::ML,
            "m_r" => ParamName::MR,
            "m_r*b_r" => ParamName::MrBr,
            "m_l*b_l" => ParamName::MlBl,
            "c" => ParamName::C,
            "s_l" => ParamName::SL,
            "s_r" => ParamName::SR,
            "m" => ParamName::M,
            "m*s_l" => ParamName::MSl,
            "m*s_r" => ParamName::MSr,
            "m_l*s_l" => ParamName::MlSl,
            "m_r*s_r" => ParamName::MrSr,
            _ => {
                let indexed = |prefix: char| t.strip_prefix(prefix).and_then(index);
                let kink_knot = t
                    .strip_prefix('d')
                    .and_then(|r| r.split_once("*p"))
                    .and_then(|(i, j)| (index(i).is_some() && i == j).then(|| index(i)).flatten());
                if let Some(i) = indexed('a') {
                    ParamName::A(i)
                } else if let Some(j) = indexed('b') {
                    ParamName::B(j)
                } else if let Some(i) = indexed('p') {
                    ParamName::Knot(i)
                } else if let Some(i) = t.strip_prefix('s').and_then(|r| r.parse::<usize>().ok()) {
                    ParamName::Slope(i)
                } else if let Some(i) = indexed('d') {
                    ParamName::Kink(i)
                } else if let Some(i) = kink_knot {
                    ParamName::KinkKnot(i)
                } else if let Some(i) = indexed('g') {
                    ParamName::Poly(i)
                } else {
                    return Err(SysidError::Data(format!(
                        "'{t}' is not a parameter name (b_l, b_r, m_l, m_r, s_l, s_r, m, p1.., s0.., g1.., a1.., b1.., c)"
                    )));
                }
            }
        })
    }
}

/// Which vector layout a [`Parameterisation`] uses (module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Layout {
    /// θ of the linear regression (key-term separation).
    KeyTerm,
    /// The model's own parameters (breakpoints and slopes).
    Physical,
}

/// A structure's parameter vector: its layout, the names, which entries are free, and the maps to and
/// from a [`Model`]. Fixed entries keep the value they have in the full vector.
#[derive(Debug, Clone, PartialEq)]
pub struct Parameterisation {
    structure: Structure,
    layout: Layout,
    free: Vec<bool>,
}

impl Parameterisation {
    /// Every parameter of `structure` free, in `layout`.
    pub fn new(structure: Structure, layout: Layout) -> Self {
        let free = vec![true; structure.n_params()];
        Parameterisation {
            structure,
            layout,
            free,
        }
    }

    /// Every parameter of `model`'s own structure (kind, orders, offset) free, in `layout`.
    pub fn of_model(model: &Model, layout: Layout) -> Self {
        let structure = Structure {
            kind: model.kind(),
            orders: model.orders(),
            offset: model.offset().is_some(),
        };
        Parameterisation::new(structure, layout)
    }

    /// The same with the free mask `free` (one entry per parameter); fails on a length mismatch.
    pub fn with_free(mut self, free: Vec<bool>) -> Result<Self, SysidError> {
        if free.len() != self.free.len() {
            return Err(SysidError::Data(format!(
                "a free-parameter mask of {} entries for {} parameters",
                free.len(),
                self.free.len()
            )));
        }
        self.free = free;
        Ok(self)
    }

    /// The structure.
    pub fn structure(&self) -> &Structure {
        &self.structure
    }

    /// The layout.
    pub fn layout(&self) -> Layout {
        self.layout
    }

    /// Number of parameters (free and fixed).
    pub fn len(&self) -> usize {
        self.free.len()
    }

    /// True when the structure has no parameter.
    pub fn is_empty(&self) -> bool {
        self.free.is_empty()
    }

    /// Which entries are free.
    pub fn free(&self) -> &[bool] {
        &self.free
    }

    /// Indices of the free entries.
    pub fn free_indices(&self) -> Vec<usize> {
        (0..self.free.len()).filter(|&i| self.free[i]).collect()
    }

    /// Number of free entries.
    pub fn n_free(&self) -> usize {
        self.free.iter().filter(|f| **f).count()
    }

    /// True when every entry is free.
    pub fn all_free(&self) -> bool {
        self.free.iter().all(|f| *f)
    }

    /// The names of the entries, in order.
    pub fn names(&self) -> Vec<ParamName> {
        let s = &self.structure;
        let o = s.orders;
        let mut v = Vec::with_capacity(self.len());
        let hammer = s.kind == ModelKind::Hammerstein;
        if hammer {
            v.extend(match self.layout {
                Layout::KeyTerm => [
                    ParamName::MR,
                    ParamName::MrBr,
                    ParamName::ML,
                    ParamName::MlBl,
                ],
                Layout::Physical => [ParamName::BL, ParamName::BR, ParamName::ML, ParamName::MR],
            });
        }
        v.extend((1..=o.na).map(ParamName::A));
        v.extend((if hammer { 2 } else { 1 }..=o.nb).map(ParamName::B));
        if s.offset {
            v.push(ParamName::C);
        }
        v
    }

    /// The names as strings (for messages and solvers).
    pub fn name_strings(&self) -> Vec<String> {
        self.names().iter().map(ToString::to_string).collect()
    }

    /// The full parameter vector of `model` in this layout.
    pub fn vector_of(&self, model: &Model) -> Vec<f64> {
        let mut v = Vec::with_capacity(self.len());
        let skip_b1 = match model.deadzone() {
            Some(d) => {
                match self.layout {
                    Layout::KeyTerm => v.extend([d.m_r, d.m_r * d.b_r, d.m_l, d.m_l * d.b_l]),
                    Layout::Physical => v.extend([d.b_l, d.b_r, d.m_l, d.m_r]),
                }
                1
            }
            None => 0,
        };
        v.extend_from_slice(model.a());
        v.extend(model.b().iter().skip(skip_b1));
        v.extend(model.offset());
        v
    }

    /// The full parameter vector of `model` in this layout, each entry with its name (b1 of a Hammerstein
    /// model is fixed at 1 and not an entry).
    pub fn named_vector_of(&self, model: &Model) -> Vec<(ParamName, f64)> {
        self.names()
            .into_iter()
            .zip(self.vector_of(model))
            .collect()
    }

    /// The model with the full parameter vector `v` (key-term breakpoints as the ratios θ2/θ1 and θ4/θ3,
    /// 0 where a slope is 0); fails on a length mismatch or non-finite values.
    pub fn model_of(&self, v: &[f64], ts: f64) -> Result<Model, SysidError> {
        if v.len() != self.len() {
            return Err(SysidError::Data(format!(
                "a parameter vector of {} entries for {} parameters",
                v.len(),
                self.len()
            )));
        }
        let s = &self.structure;
        let o = s.orders;
        let mut i = 0;
        let deadzone = (s.kind == ModelKind::Hammerstein).then(|| {
            i = 4;
            match self.layout {
                Layout::KeyTerm => deadzone_from_theta(v, ZERO_DEADZONE, f64::INFINITY),
                Layout::Physical => Deadzone {
                    b_l: v[0],
                    b_r: v[1],
                    m_l: v[2],
                    m_r: v[3],
                },
            }
        });
        let a = v[i..i + o.na].to_vec();
        i += o.na;
        let mut b = Vec::with_capacity(o.nb);
        if s.kind == ModelKind::Hammerstein {
            b.push(1.0);
            b.extend_from_slice(&v[i..i + o.nb - 1]);
            i += o.nb - 1;
        } else {
            b.extend_from_slice(&v[i..i + o.nb]);
            i += o.nb;
        }
        let offset = s.offset.then(|| v[i]);
        Model::siso(s.kind, ts, a, b, o.nk, deadzone, offset)
    }

    /// The free entries of the full vector `full`.
    pub fn gather(&self, full: &[f64]) -> Vec<f64> {
        full.iter()
            .zip(&self.free)
            .filter(|(_, f)| **f)
            .map(|(v, _)| *v)
            .collect()
    }

    /// `base` with its free entries replaced by `sub` (in order).
    pub fn scatter(&self, sub: &[f64], base: &[f64]) -> Vec<f64> {
        let mut out = base.to_vec();
        let free = out.iter_mut().zip(&self.free).filter(|(_, f)| **f);
        for ((o, _), s) in free.zip(sub) {
            *o = *s;
        }
        out
    }

    /// A full-size matrix with the free-by-free block `sub` in place and zeros elsewhere (for
    /// covariances).
    pub fn scatter_matrix(&self, sub: &DMatrix<f64>) -> DMatrix<f64> {
        let idx = self.free_indices();
        let mut full = DMatrix::zeros(self.len(), self.len());
        for (a, &i) in idx.iter().enumerate() {
            for (b, &j) in idx.iter().enumerate() {
                full[(i, j)] = sub[(a, b)];
            }
        }
        full
    }
}

/// The deadzone with every parameter 0 (a start value).
pub const ZERO_DEADZONE: Deadzone = Deadzone {
    b_l: 0.0,
    b_r: 0.0,
    m_l: 0.0,
    m_r: 0.0,
};

/// Deadzone from key-term θ = [m_r, m_r b_r, m_l, m_l b_l, ...]. A breakpoint whose ratio is not finite
/// (slope 0) keeps its `prev` value; breakpoints are clamped to ±`limit` so that a wild early estimate
/// cannot switch a branch off for the whole record.
pub fn deadzone_from_theta(theta: &[f64], prev: Deadzone, limit: f64) -> Deadzone {
    let ratio = |num: f64, den: f64, prev: f64| {
        let r = num / den;
        if r.is_finite() {
            r.clamp(-limit, limit)
        } else {
            prev
        }
    };
    Deadzone {
        b_r: ratio(theta[1], theta[0], prev.b_r),
        b_l: ratio(theta[3], theta[2], prev.b_l),
        m_r: theta[0],
        m_l: theta[2],
    }
}

/// Withholds every standard deviation that is exactly 0 (sets it to `None`) and returns the labels of
/// those withheld. A standard deviation of exactly 0 claims a certainty no finite record gives: it comes
/// from a covariance that underflowed (signals many orders of magnitude apart) or is degenerate (a
/// pseudo-inverse of a singular information matrix gives 0 where the data say nothing). The one rule of
/// `identify` (`sysid::estimate`, when the residuals are not zero) and `calibrate` (whose record cannot
/// fit exactly: a still record gives J = 0).
pub fn withhold_zero_stds<'a>(
    stds: impl IntoIterator<Item = (String, &'a mut Option<f64>)>,
) -> Vec<String> {
    let mut withheld = Vec::new();
    for (label, std) in stds {
        if *std == Some(0.0) {
            *std = None;
            withheld.push(label);
        }
    }
    withheld
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Orders;

    fn hammer(offset: bool) -> Structure {
        Structure {
            kind: ModelKind::Hammerstein,
            orders: Orders {
                na: 2,
                nb: 2,
                nk: 1,
            },
            offset,
        }
    }

    // The paper's model in the key-term layout: θ = [m_r, m_r b_r, m_l, m_l b_l, a1, a2, a3].
    #[test]
    fn key_term_vector_of_the_paper_model_is_products_of_slopes_and_breakpoints() {
        let s = Structure {
            kind: ModelKind::Hammerstein,
            orders: Orders::PAPER,
            offset: false,
        };
        let p = Parameterisation::new(s, Layout::KeyTerm);
        let v = p.vector_of(&Model::paper());
        let (mr, ml) = (2.38 * 15.67e-4, 3.46 * 15.67e-4);
        let want = [mr, mr * 1.41, ml, ml * -1.50, -1.869, 0.9976, -0.1284];
        assert_eq!(v.len(), want.len());
        for (a, b) in v.iter().zip(want) {
            assert!((a - b).abs() <= 1e-15 * b.abs().max(1.0), "{a} vs {b}");
        }
        let names: Vec<String> = p.name_strings();
        assert_eq!(
            names,
            ["m_r", "m_r*b_r", "m_l", "m_l*b_l", "a1", "a2", "a3"]
        );
    }

    // A model's own parameterisation names its entries: for a Hammerstein model with offset,
    // b_l, b_r, m_l, m_r, a1, a2, b2, c with the values the model was built from.
    #[test]
    fn of_model_names_every_entry_of_the_model() {
        let dz = Deadzone {
            b_l: -30.0,
            b_r: 25.0,
            m_l: 0.004,
            m_r: 0.005,
        };
        let m = Model::siso(
            ModelKind::Hammerstein,
            0.01,
            vec![-1.5, 0.6],
            vec![1.0, 0.3],
            1,
            Some(dz),
            Some(0.7),
        )
        .unwrap();
        let p = Parameterisation::of_model(&m, Layout::Physical);
        assert_eq!(p.structure(), &hammer(true));
        assert_eq!(
            p.named_vector_of(&m),
            [
                (ParamName::BL, -30.0),
                (ParamName::BR, 25.0),
                (ParamName::ML, 0.004),
                (ParamName::MR, 0.005),
                (ParamName::A(1), -1.5),
                (ParamName::A(2), 0.6),
                (ParamName::B(2), 0.3),
                (ParamName::C, 0.7)
            ]
        );
    }

    // Physical vector → model → physical vector is the identity.
    #[test]
    fn physical_layout_round_trips_through_a_model() {
        let p = Parameterisation::new(hammer(true), Layout::Physical);
        let v = vec![-30.0, 25.0, 0.004, 0.005, -1.5, 0.6, 0.3, 0.7];
        let m = p.model_of(&v, 0.01).unwrap();
        assert_eq!(m.b(), &[1.0, 0.3]);
        assert_eq!(m.offset(), Some(0.7));
        assert_eq!(p.vector_of(&m), v);
        assert_eq!(
            p.names(),
            [
                ParamName::BL,
                ParamName::BR,
                ParamName::ML,
                ParamName::MR,
                ParamName::A(1),
                ParamName::A(2),
                ParamName::B(2),
                ParamName::C
            ]
        );
    }

    // Gather picks the free entries; scatter puts them back over a base; the matrix keeps zeros outside.
    #[test]
    fn gather_and_scatter_are_inverse_on_the_free_entries() {
        let s = Structure {
            kind: ModelKind::Arx,
            orders: Orders {
                na: 1,
                nb: 2,
                nk: 1,
            },
            offset: false,
        };
        let p = Parameterisation::new(s, Layout::KeyTerm)
            .with_free(vec![true, false, true])
            .unwrap();
        assert_eq!(p.gather(&[1.0, 2.0, 3.0]), [1.0, 3.0]);
        assert_eq!(p.scatter(&[7.0, 9.0], &[1.0, 2.0, 3.0]), [7.0, 2.0, 9.0]);
        let m = p.scatter_matrix(&DMatrix::from_row_slice(2, 2, &[1.0, 2.0, 3.0, 4.0]));
        assert_eq!(
            m,
            DMatrix::from_row_slice(3, 3, &[1.0, 0.0, 2.0, 0.0, 0.0, 0.0, 3.0, 0.0, 4.0])
        );
        assert!(p.clone().with_free(vec![true]).is_err());
    }

    #[test]
    fn names_parse_back() {
        for n in [
            ParamName::BL,
            ParamName::MlBl,
            ParamName::A(3),
            ParamName::B(12),
            ParamName::C,
        ] {
            assert_eq!(n.to_string().parse::<ParamName>().unwrap(), n);
        }
        assert!("x1".parse::<ParamName>().is_err());
        assert!("a0".parse::<ParamName>().is_err());
    }
}
