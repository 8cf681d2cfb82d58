//! One module per subcommand, and the options they share.

pub mod build_args;
pub mod info;
pub mod trace;
