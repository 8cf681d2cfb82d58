//! `hbv experiment ...`: measurements that answer one question each and print a table.

pub mod dynamic;

use clap::{Args, Subcommand};

#[derive(Args)]
pub struct ExperimentArgs {
    #[command(subcommand)]
    pub experiment: Experiment,
}

#[derive(Subcommand)]
pub enum Experiment {
    /// The dynamic BVH: cost per insert, remove and refit, and the tree's quality after
    /// removing and reinserting, or moving, 10%, 50% and 100% of the triangles.
    Dynamic(dynamic::DynamicArgs),
}

pub fn run(args: &ExperimentArgs) -> anyhow::Result<()> {
    match &args.experiment {
        Experiment::Dynamic(a) => dynamic::run(a),
    }
}
