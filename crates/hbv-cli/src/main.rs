//! `hbv`: inspect, build and trace bounding volume hierarchies from the command line.

mod commands;

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[derive(Parser)]
#[command(
    name = "hbv",
    version,
    about = "Hierarchical bounding volumes for ray tracing triangle meshes"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Build a tree over a mesh (or the built-in scene) and report its shape and cost E[X].
    Info(commands::info::InfoArgs),
    /// Trace a ray file against a mesh and write the hits (file formats: ../shared/RAYS.md).
    Trace(commands::trace::TraceArgs),
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Command::Info(args) => commands::info::run(&args),
        Command::Trace(args) => commands::trace::run(&args),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // One line: the context chain, outermost first.
            eprintln!("hbv: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
