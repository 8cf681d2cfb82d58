//! The .hbv reader on arbitrary bytes: it must return a tree or an error, never panic, hang or
//! allocate what a lying header declares. Each input is read twice: as it is (the checksums
//! reject nearly every mutation) and with both CRC-32s recomputed at their documented places
//! (docs/BVH_FILE.md), so that mutated headers, sizes and trees reach the checks behind the
//! checksums. A file the reader accepts is laid out and traced (`hbv_fuzz::exercise_tree`): a
//! tree that passed its checks must be safe to use.
#![no_main]

use std::path::Path;

use hbv::bvh::file::BvhFile;
use libfuzzer_sys::fuzz_target;

/// Header bytes; the payload's CRC is at 56..60, the header's (of bytes 0..60) at 60..64.
const HEADER: usize = 64;

fuzz_target!(|data: &[u8]| {
    let mut fixed = data.to_vec();
    if fixed.len() >= HEADER {
        let payload = crc32fast::hash(&fixed[HEADER..]);
        fixed[56..60].copy_from_slice(&payload.to_le_bytes());
        let header = crc32fast::hash(&fixed[..60]);
        fixed[60..64].copy_from_slice(&header.to_le_bytes());
    }
    for bytes in [data, &fixed[..]] {
        if let Ok(file) = BvhFile::from_bytes(bytes, Path::new("fuzz.hbv")) {
            hbv_fuzz::exercise_tree(&file.tree, &file.mesh);
        }
    }
});
