//! Reading and checking `.hbv` scene files (layout in `scene_format.rs`).

use super::error::BvhFileProblem;
use super::format::{check_kind, check_section_ends, BvhFileKind, HEADER_SIZE};
use super::read::parse_leading;
use super::scene_format::{
    origin_from_bytes, SceneHeader, StoredInstance, StoredStructure, INSTANCE_SIZE, ORIGIN_SIZE,
    STRUCTURE_SIZE,
};
use super::BvhFile;

/// A scene file's contents as stored, every part checked but the instances' transforms (the
/// scene's to check).
pub(crate) struct StoredScene {
    pub structure: StoredStructure,
    pub instances: Vec<StoredInstance>,
    /// Each mesh with its tree and settings line, and the origin of its stored vertices, by
    /// mesh id.
    pub meshes: Vec<(BvhFile, [f64; 3])>,
}

/// Parses a scene file: the header and its declared sizes against the file's length (before
/// anything is allocated), the record section's CRC-32, each record, then each mesh file in
/// turn as [`BvhFile::from_bytes`] checks one, and no bytes after the last.
pub(crate) fn parse_scene(bytes: &[u8]) -> Result<StoredScene, BvhFileProblem> {
    check_kind(bytes, BvhFileKind::Scene)?;
    let header = SceneHeader::from_bytes(bytes)?;
    let len = bytes.len() as u64;
    let records = [
        ("structure", Some(STRUCTURE_SIZE as u64)),
        ("origins", header.meshes.checked_mul(ORIGIN_SIZE as u64)),
        (
            "instances",
            header.instances.checked_mul(INSTANCE_SIZE as u64),
        ),
    ];
    let records_end = check_section_ends(HEADER_SIZE as u64, records, len)?;
    // Each mesh file is at least a header long: a lying mesh count is caught here too.
    let least_meshes = ("meshes", header.meshes.checked_mul(HEADER_SIZE as u64));
    check_section_ends(records_end, [least_meshes], len)?;
    // Both ends are within `bytes`, so they fit in usize.
    let records_end = records_end as usize;
    let computed = crc32fast::hash(&bytes[HEADER_SIZE..records_end]);
    if computed != header.records_crc {
        return Err(BvhFileProblem::Checksum {
            part: "record section",
            stored: header.records_crc,
            computed,
        });
    }
    let structure = StoredStructure::from_bytes(&bytes[HEADER_SIZE..])?;
    let origins_start = HEADER_SIZE + STRUCTURE_SIZE;
    // The mesh count fits in memory: its origins are in `bytes`.
    let instances_start = origins_start + header.meshes as usize * ORIGIN_SIZE;
    let origins = bytes[origins_start..instances_start]
        .chunks_exact(ORIGIN_SIZE)
        .enumerate()
        .map(|(id, record)| origin_from_bytes(record, id))
        .collect::<Result<Vec<_>, _>>()?;
    let instances = bytes[instances_start..records_end]
        .chunks_exact(INSTANCE_SIZE)
        .enumerate()
        .map(|(id, record)| StoredInstance::from_bytes(record, id, header.meshes))
        .collect::<Result<Vec<_>, _>>()?;
    let mut meshes = Vec::with_capacity(origins.len());
    let mut at = records_end;
    for (mesh, origin) in (0u64..).zip(origins) {
        let (file, size) =
            parse_leading(&bytes[at..]).map_err(|problem| BvhFileProblem::InMesh {
                mesh,
                problem: Box::new(counted_from_file_start(problem, at as u64)),
            })?;
        meshes.push((file, origin));
        at += size;
    }
    if at < bytes.len() {
        return Err(BvhFileProblem::TrailingBytes {
            expected: at as u64,
            len,
        });
    }
    Ok(StoredScene {
        structure,
        instances,
        meshes,
    })
}

/// A problem of the mesh file that starts at byte `start`, its byte counts made the scene
/// file's.
fn counted_from_file_start(problem: BvhFileProblem, start: u64) -> BvhFileProblem {
    match problem {
        BvhFileProblem::Truncated {
            section,
            needed,
            len,
        } => BvhFileProblem::Truncated {
            section,
            needed: needed + start,
            len: len + start,
        },
        other => other,
    }
}
