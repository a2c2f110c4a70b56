//! One module per subcommand: its flags (`Args`) and its `run`.

pub mod bench;
pub mod bench_narx;
pub mod bench_oe;
pub mod calibrate;
pub mod common;
pub mod control;
pub mod delay;
pub mod identify;
pub mod identify_batch;
pub mod identify_narx;
pub mod montecarlo;
pub mod order;
pub mod order_classes;
pub mod plant_config;
pub mod reproduce;
pub mod response;
pub mod simulate;
pub mod simulate_fleet;
pub mod track;
pub mod track_stream;
pub mod tune;
pub mod validate;
