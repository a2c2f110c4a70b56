//! `sysid-studies`: studies of the estimators of crate `sysid` — Monte-Carlo runs for bias and spread
//! ([`montecarlo`]) and speed benchmarks ([`bench`], [`oe_bench`]). Application code: it may use threads (rayon) and
//! random numbers (rand), which the identification library itself does not.

pub mod bench;
pub mod long;
pub mod montecarlo;
pub mod narx_bench;
pub mod oe_bench;
pub mod rng;
