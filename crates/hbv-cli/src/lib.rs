//! The library behind the `hbv` command line: reading ray files, writing hit files (the `.npz`
//! formats of `docs/RAYS.md`), and replacing output files atomically.

pub mod hit_file;
pub mod hit_file_writer;
mod npy_header;
mod npz_in_place;
mod npz_writer;
pub mod output_check;
pub mod plot;
pub mod ray_file;
pub mod ray_sets;
pub mod ray_stream;
