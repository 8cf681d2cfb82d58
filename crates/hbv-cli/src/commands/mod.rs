//! One module per subcommand, and the options they share.

pub mod bench;
pub mod build;
pub mod build_args;
pub mod build_compare;
pub mod experiment;
pub mod flag_values;
pub mod info;
pub mod median;
pub mod name_values;
pub mod render;
pub mod scene_bench;
pub mod scene_info;
pub mod trace;
pub mod trace_progress;
