//! `hbv experiment ...`: measurements that answer one question each and print a table.

pub mod dynamic;
pub mod seed_claims;

use clap::{Args, Subcommand};

#[derive(Args)]
pub struct ExperimentArgs {
    #[command(subcommand)]
    pub experiment: Experiment,
}

#[derive(Subcommand)]
pub enum Experiment {
    /// The seed's claims on grids, BVHs, caches and mailboxes, measured: grid vs every BVH
    /// layout on camera, reflection, diffuse and shadow rays, with and without mailboxes and
    /// object caches.
    SeedClaims(seed_claims::SeedClaimsArgs),
    /// The dynamic BVH: cost per insert, remove and refit, and the tree's quality after
    /// removing and reinserting, or moving, 10%, 50% and 100% of the triangles.
    Dynamic(dynamic::DynamicArgs),
}

/// Runs the experiment named.
pub fn run(args: &ExperimentArgs) -> anyhow::Result<()> {
    match &args.experiment {
        Experiment::SeedClaims(a) => seed_claims::run(a),
        Experiment::Dynamic(a) => dynamic::run(a),
    }
}
