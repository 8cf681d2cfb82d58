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
    // A bug must still end in one clear line, not a backtrace dump.
    std::panic::set_hook(Box::new(|info| {
        let location = info
            .location()
            .map(|l| format!(" at {l}"))
            .unwrap_or_default();
        let message = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "unknown cause".into());
        eprintln!("hbv: internal error{location}: {message} (please report it)");
    }));
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
