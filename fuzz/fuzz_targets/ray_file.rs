//! The ray file reader (`.npz`, see docs/RAYS.md) on arbitrary bytes: rays or an error naming
//! the member, never a panic or an allocation the header asks for but the data cannot fill.
#![no_main]

use std::io::Cursor;
use std::path::Path;

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let _ = hbv_cli::ray_file::read_rays_from(Path::new("fuzz.npz"), Cursor::new(data.to_vec()));
});
