//! `hbv experiment ...`: measurements that answer one question each and print a table.

pub mod dynamic;
pub mod instanced_field;
pub mod seed_claims;
pub mod seed_claims_scene;
pub mod traced;

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
    /// object caches; on a scene (.gltf, .glb, or --scene-default), the two-level scene and its
    /// (instance, prim) caches against a BVH and a grid over its flattened triangles.
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
