//! `ipa-sysid plant-config`: prints the physics plant's default parameters as commented TOML.

/// Flags of `plant-config` (none: the TOML goes to stdout; redirect it to a file and edit it).
#[derive(Debug, clap::Args)]
pub struct Args {}

/// Prints the defaults as TOML with the unit and source of every value.
pub fn run(_args: Args) -> anyhow::Result<()> {
    super::common::print_stdout(&ipa::PlantConfig::default().to_commented_toml())
}
