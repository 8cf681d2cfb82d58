//! `hbv experiment`: measurements that put a claim to the test, one subcommand each.

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
}

/// Runs the experiment named.
pub fn run(args: &ExperimentArgs) -> anyhow::Result<()> {
    match &args.experiment {
        Experiment::SeedClaims(a) => seed_claims::run(a),
    }
}
