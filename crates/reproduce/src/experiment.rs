//! Stage 1: the experiments on the plant (staircase records for estimation and validation, the open-loop
//! test).

use sysid::data::Signals;
use sysid::{Dataset, Plant};

use crate::ReproduceError;

pub(crate) fn record(
    plant: &mut dyn Plant,
    u: Vec<f64>,
    start_mm: f64,
    name: &str,
) -> Result<Dataset, ReproduceError> {
    plant.reset(start_mm);
    let y = sysid::plant::run_open_loop(plant, &u)?;
    Ok(Dataset::new(Signals { u, y }, plant.ts(), name)?)
}
