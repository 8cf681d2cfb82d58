//! `hbv`: inspect, build and trace bounding volume hierarchies from the command line.

mod commands;

use std::process::ExitCode;

use clap::{CommandFactory, FromArgMatches, Parser, Subcommand};

/// mimalloc rather than the C library's allocator. After a build over a large mesh, glibc
/// coalesces the build's many freed small blocks at the next large request, the trace's answer
/// array: on the 871,414-triangle dragon that took 62 million instructions (946 a ray of 65,536
/// camera rays, `malloc_consolidate`), and the first trace of a run 17–24 ms against 7–10 ms for
/// the next ones. The CLI times that trace; a Python user's calls go through hbv-py, which uses
/// mimalloc too.
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

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
    /// Build a tree over a mesh (or the built-in scene) and report its shape and cost E[X]; on a
    /// scene (glTF, or a saved .hbv scene), its meshes, instances and costs.
    Info(commands::info::InfoArgs),
    /// Trace a ray file against a mesh or a scene and write the hits (file formats:
    /// docs/RAYS.md).
    Trace(commands::trace::TraceArgs),
    /// Measure rays per second of every layout on camera, diffuse and shadow rays.
    Bench(commands::bench::BenchArgs),
    /// Every builder on one table: build time, tree shape, predicted cost E[X] and the tests
    /// actually counted on isotropic lines and real rays.
    BuildCompare(commands::build_compare::BuildCompareArgs),
    /// Build a mesh's tree, or each mesh of a glTF scene, and save it in a .hbv file, which
    /// info, trace and bench load without building again (format: docs/BVH_FILE.md).
    Build(commands::build::BuildCommandArgs),
    /// Experiments that each answer one question with a table (see BENCHMARKS.md):
    /// `seed-claims`, `dynamic`.
    Experiment(commands::experiment::ExperimentArgs),
    /// Render a scene (or the built-in Cornell box) to PNG/OpenEXR, with passes and heatmaps.
    Render(commands::render::RenderArgs),
}

/// `command` with every flag of it and of its subcommands taking a value that looks like a
/// negative number: `--rays -5` is then refused by the flag's own check, which names the flag
/// and what it takes, instead of being read as an unknown flag `-5`.
fn negative_numbers_as_values(command: clap::Command) -> clap::Command {
    command
        .mut_args(|arg| {
            // (Only arguments that take a value may: clap asserts it of switches.)
            let takes_value = arg.get_action().takes_values();
            arg.allow_negative_numbers(takes_value)
        })
        .mut_subcommands(negative_numbers_as_values)
}

fn main() -> ExitCode {
    // Like every Unix filter: a reader that closes the pipe (`hbv ... | head`) ends the program
    // quietly instead of making each `println!` fail.
    #[cfg(unix)]
    // SAFETY: restoring the default action of SIGPIPE before any thread starts.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    // Interrupted (Ctrl-C, SIGTERM) while writing an output: its temporary file goes too. The
    // output itself is whole or untouched either way (written atomically).
    let _ = ctrlc::set_handler(|| {
        hbv::atomic_file::remove_temporaries();
        eprintln!("hbv: interrupted");
        std::process::exit(130);
    });
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
    let cli = Cli::from_arg_matches(&negative_numbers_as_values(Cli::command()).get_matches())
        .unwrap_or_else(|e| e.exit());
    let result = match cli.command {
        Command::Info(args) => commands::info::run(&args),
        Command::Trace(args) => commands::trace::run(&args),
        Command::Bench(args) => commands::bench::run(&args),
        Command::BuildCompare(args) => commands::build_compare::run(&args),
        Command::Build(args) => commands::build::run(&args),
        Command::Experiment(args) => commands::experiment::run(&args),
        Command::Render(args) => commands::render::run(&args),
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
