//! Bad input to the `hbv` command line: every row of the table in docs/RELIABILITY.md that the
//! CLI answers is backed by a test here. Each bad run exits non-zero with exactly one line on
//! stderr (`hbv: error: ...`) that names the file, the place and the reason, no panic message,
//! and leaves no output file, half-written or temporary, behind (and an existing one untouched).

use std::ffi::OsStr;
use std::io::{Cursor, Write};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

use glam::Vec3;
use hbv::geometry::Ray;
use hbv_cli::{hit_file, ray_file};
use tempfile::TempDir;
use zip::write::SimpleFileOptions;

const TETRA_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

fn hbv<S: AsRef<OsStr>>(args: &[S]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_hbv"))
        .args(args)
        .output()
        .expect("the hbv binary runs")
}

/// A folder with a good mesh (`tetra.obj`) and good rays (`rays.npz`).
struct Scene {
    dir: TempDir,
}

impl Scene {
    fn new() -> Self {
        let dir = TempDir::new().unwrap();
        std::fs::write(dir.path().join("tetra.obj"), TETRA_OBJ).unwrap();
        let rays = [
            Ray::new(Vec3::new(0.2, 0.2, -1.0), Vec3::Z),
            Ray::new(Vec3::new(5.0, 5.0, 5.0), Vec3::X),
        ];
        ray_file::write_rays(
            &dir.path().join("rays.npz"),
            &rays,
            hbv::atomic_file::Replace::Always,
        )
        .unwrap();
        Self { dir }
    }

    fn path(&self, name: impl AsRef<Path>) -> PathBuf {
        self.dir.path().join(name)
    }

    fn write(&self, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
        let path = self.path(name);
        std::fs::write(&path, bytes).unwrap();
        path
    }

    fn files(&self) -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(self.dir.path())
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    /// Runs `hbv trace MESH --rays RAYS --out hits.npz`, which must fail, and returns its one
    /// line of error after checking that no output (or temporary file) was left.
    fn trace_error(&self, mesh: &Path, rays: &Path) -> String {
        let before = self.files();
        let out = self.path("hits.npz");
        let output = hbv(&[
            OsStr::new("trace"),
            mesh.as_os_str(),
            OsStr::new("--rays"),
            rays.as_os_str(),
            OsStr::new("--out"),
            out.as_os_str(),
        ]);
        let line = one_error_line(&output);
        assert_eq!(self.files(), before, "files changed: {line}");
        line
    }
}

/// Checks a failed run: non-zero exit, nothing but one `hbv: error:` line on stderr, no panic.
fn one_error_line(output: &Output) -> String {
    let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
    assert!(!output.status.success(), "succeeded; stderr: {stderr}");
    assert_eq!(output.status.code(), Some(1), "{stderr}");
    assert!(
        stderr.starts_with("hbv: error: ") && stderr.ends_with('\n'),
        "{stderr}"
    );
    assert_eq!(stderr.lines().count(), 1, "{stderr}");
    assert!(
        !stderr.contains("panicked") && !stderr.contains("internal error"),
        "{stderr}"
    );
    stderr.trim_end().to_owned()
}

/// A `.npy` member: header text as NumPy writes it (padded to 64 bytes), then `data`.
fn npy(descr: &str, shape: &str, data: &[u8]) -> Vec<u8> {
    let header = format!("{{'descr': '{descr}', 'fortran_order': False, 'shape': {shape}, }}");
    npy_with_header(&header, data)
}

/// A `.npy` member whose header holds `header` (a dict literal, or not), padded as NumPy pads it.
fn npy_with_header(header: &str, data: &[u8]) -> Vec<u8> {
    let mut header = header.to_owned();
    while !(10 + header.len() + 1).is_multiple_of(64) {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend((header.len() as u16).to_le_bytes());
    bytes.extend(header.as_bytes());
    bytes.extend(data);
    bytes
}

fn f32s(values: &[f32]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

/// An `.npz` archive of the given members (uncompressed, as `numpy.savez` writes).
fn npz(members: &[(&str, Vec<u8>)]) -> Vec<u8> {
    let mut zip = zip::ZipWriter::new(Cursor::new(Vec::new()));
    let options = SimpleFileOptions::default().compression_method(zip::CompressionMethod::Stored);
    for (name, bytes) in members {
        zip.start_file(*name, options).unwrap();
        zip.write_all(bytes).unwrap();
    }
    zip.finish().unwrap().into_inner()
}

fn good_origins() -> Vec<u8> {
    npy("<f4", "(1, 3)", &f32s(&[0.2, 0.2, -1.0]))
}

// ------------------------------------------------------------------ meshes

#[test]
fn bad_meshes_are_one_line_naming_file_place_and_reason() {
    let s = Scene::new();
    let rays = s.path("rays.npz");
    let cases: [(&str, &[u8], &str); 6] = [
        (
            "empty.obj",
            b"",
            "empty.obj: file: no triangles (the file has no faces)",
        ),
        (
            "range.obj",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
            "range.obj: line 4: vertex index 9 out of range (the file has 3 vertices)",
        ),
        (
            "nan.obj",
            b"v 0 0 0\nv 1 nan 0\nv 0 1 0\nf 1 2 3\n",
            "nan.obj: line 2: vertex coordinate is not finite: \"v 1 nan 0\"",
        ),
        (
            "cut.ply",
            b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
              property float y\nproperty float z\nend_header\n\0\0\0\0",
            "cut.ply: vertex 0: unexpected end of file: the file is truncated \
             (the header declares 3 'vertex' elements)",
        ),
        (
            "cut.glb",
            b"glTF\x02\0\0\0",
            "cut.glb: file: not valid glTF",
        ),
        (
            "latin1.ply",
            b"ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
              property float z\nend_header\n0 0 \xe9\n",
            "latin1.ply: vertex 0 (line 8): line is not valid UTF-8",
        ),
    ];
    for (name, bytes, reason) in cases {
        let mesh = s.write(name, bytes);
        let line = s.trace_error(&mesh, &rays);
        // A glTF file is a scene (docs/RAYS.md, "Scenes (glTF)"), read by the same parser.
        let what = if name.ends_with(".glb") {
            "scene"
        } else {
            "mesh"
        };
        assert!(
            line.starts_with(&format!("hbv: error: cannot load {what}: ")),
            "{line}"
        );
        assert!(line.contains(reason), "{name}: {line}");
        std::fs::remove_file(mesh).unwrap();
    }
}

#[test]
fn missing_mesh_directory_and_unknown_format_are_one_line() {
    let s = Scene::new();
    let rays = s.path("rays.npz");
    let line = s.trace_error(&s.path("missing.obj"), &rays);
    assert!(
        line.ends_with("missing.obj: cannot read: No such file or directory (os error 2)"),
        "{line}"
    );
    std::fs::create_dir(s.path("folder.ply")).unwrap();
    let line = s.trace_error(&s.path("folder.ply"), &rays);
    assert!(
        line.ends_with("folder.ply: cannot read: Is a directory (os error 21)"),
        "{line}"
    );
    let line = s.trace_error(&s.write("mesh.stl", "solid"), &rays);
    assert!(
        line.ends_with("mesh.stl: unsupported mesh format (expected .obj, .ply, .gltf or .glb)"),
        "{line}"
    );
}

#[cfg(unix)]
#[test]
fn non_utf8_mesh_name_is_shown_with_replacement_characters() {
    use std::os::unix::ffi::OsStrExt;
    let s = Scene::new();
    let name = OsStr::from_bytes(b"m\xe9sh.obj");
    std::fs::write(s.path(name), "v 0 0 0\nf 1 1\n").unwrap();
    let line = s.trace_error(&s.path(name), &s.path("rays.npz"));
    assert!(
        line.contains("m\u{fffd}sh.obj: line 2: face has 2 vertices"),
        "{line}"
    );
    // And a good mesh under such a name traces.
    std::fs::write(s.path(name), TETRA_OBJ).unwrap();
    let out = s.path(OsStr::from_bytes(b"h\xe9ts.npz"));
    let output = hbv(&[
        OsStr::new("trace"),
        s.path(name).as_os_str(),
        OsStr::new("--rays"),
        s.path("rays.npz").as_os_str(),
        OsStr::new("--out"),
        out.as_os_str(),
    ]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert_eq!(hit_file::read_hits(&out).unwrap().len(), 2);
}

#[cfg(unix)]
#[test]
fn unreadable_mesh_is_one_line_unless_privileged() {
    use std::os::unix::fs::PermissionsExt;
    let s = Scene::new();
    let mesh = s.path("tetra.obj");
    std::fs::set_permissions(&mesh, std::fs::Permissions::from_mode(0o000)).unwrap();
    if std::fs::read(&mesh).is_ok() {
        return; // root: permissions do not apply
    }
    let line = s.trace_error(&mesh, &s.path("rays.npz"));
    assert!(
        line.ends_with("tetra.obj: cannot read: Permission denied (os error 13)"),
        "{line}"
    );
}

// ------------------------------------------------------------------ ray files

#[test]
fn bad_ray_files_are_one_line_naming_member_and_reason() {
    let s = Scene::new();
    let mesh = s.path("tetra.obj");
    let dirs = || npy("<f4", "(1, 3)", &f32s(&[0.0, 0.0, 1.0]));
    let cases: Vec<(&str, Vec<u8>, &str)> = vec![
        ("empty.npz", vec![], "empty.npz is not an .npz archive"),
        ("text.npz", b"origins,directions\n".to_vec(), "text.npz is not an .npz archive"),
        (
            "nomembers.npz",
            npz(&[]),
            "nomembers.npz: no member `origins` (members: none)",
        ),
        (
            "nodirs.npz",
            npz(&[("origins.npy", good_origins())]),
            "nodirs.npz: no member `directions` or `dirs` (members: origins)",
        ),
        (
            "int.npz",
            npz(&[("origins.npy", npy("<i4", "(1, 3)", &[0; 12])), ("directions.npy", dirs())]),
            "int.npz: origins has unsupported dtype int32 ('<i4'); accepted: float32, float64",
        ),
        (
            "shape.npz",
            npz(&[("origins.npy", npy("<f4", "(3,)", &f32s(&[0.0; 3]))), ("directions.npy", dirs())]),
            "shape.npz: origins has shape (3,), expected (N, 3)",
        ),
        (
            "cols.npz",
            npz(&[("origins.npy", good_origins()), ("directions.npy", npy("<f4", "(1, 2)", &f32s(&[0.0; 2])))]),
            "cols.npz: directions has shape (1, 2), expected (N, 3)",
        ),
        (
            "rows.npz",
            npz(&[("origins.npy", good_origins()), ("directions.npy", npy("<f4", "(2, 3)", &f32s(&[1.0; 6])))]),
            "rows.npz: directions has 2 rows but origins has 1",
        ),
        (
            "tmin.npz",
            npz(&[("origins.npy", good_origins()), ("directions.npy", dirs()), ("tmin.npy", npy("<f4", "(1, 1)", &f32s(&[0.0])))]),
            "tmin.npz: tmin has shape (1, 1), expected (N,)",
        ),
        (
            // A header declaring 2^40 rows over 12 bytes of data: refused before allocating.
            "lying.npz",
            npz(&[("origins.npy", npy("<f4", "(1099511627776, 3)", &f32s(&[0.0; 3]))), ("directions.npy", dirs())]),
            "lying.npz: origins: the .npy header declares shape (1099511627776, 3) but the member holds only 140 bytes",
        ),
        (
            // A header declaring more rows than its data holds, by a little.
            "short.npz",
            npz(&[("origins.npy", npy("<f4", "(9, 3)", &f32s(&[0.0; 3]))), ("directions.npy", dirs())]),
            "short.npz: origins: the member ends before the data of shape (9, 3) its header declares",
        ),
        (
            "garbage.npz",
            npz(&[("origins.npy", b"PK garbage".to_vec()), ("directions.npy", dirs())]),
            "garbage.npz: origins: not a .npy array (it does not start with the .npy magic string)",
        ),
        (
            // A header cut inside its dictionary: the parser's six-line syntax diagram before.
            "dict.npz",
            npz(&[("origins.npy", npy_with_header("{'descr': '<f4', 'fortran_", &[])), ("directions.npy", dirs())]),
            "dict.npz: origins: the .npy header is not a Python dict literal",
        ),
        (
            // A header length of 65,535 over a 128-byte header: "failed to fill whole buffer" before.
            "headerlen.npz",
            npz(&[("origins.npy", { let mut m = good_origins(); m[8..10].copy_from_slice(&[0xff, 0xff]); m }), ("directions.npy", dirs())]),
            "headerlen.npz: origins: the .npy header says it is 65535 bytes long, longer than the member (130 bytes after its 10-byte prefix)",
        ),
        (
            "version.npz",
            npz(&[("origins.npy", { let mut m = good_origins(); m[6] = 9; m }), ("directions.npy", dirs())]),
            "version.npz: origins: .npy format version 9.0 is not supported (1.0, 2.0 and 3.0 are)",
        ),
        (
            "negative.npz",
            npz(&[("origins.npy", npy("<f4", "(-1, 3)", &[])), ("directions.npy", dirs())]),
            "negative.npz: origins: the .npy header's 'shape' is (-1, 3), expected a tuple of non-negative integers",
        ),
    ];
    for (name, bytes, reason) in cases {
        let rays = s.write(name, &bytes);
        let line = s.trace_error(&mesh, &rays);
        assert!(line.starts_with("hbv: error: cannot read rays: "), "{line}");
        assert!(line.contains(reason), "{name}: {line}");
        std::fs::remove_file(rays).unwrap();
    }
}

#[test]
fn missing_ray_file_is_one_line() {
    let s = Scene::new();
    std::fs::create_dir(s.path("folder.npz")).unwrap();
    let line = s.trace_error(&s.path("tetra.obj"), &s.path("folder.npz"));
    assert!(line.ends_with("folder.npz: it is a directory"), "{line}");
    let line = s.trace_error(&s.path("tetra.obj"), &s.path("missing.npz"));
    assert!(
        line.contains("cannot read rays: cannot open ")
            && line.ends_with("missing.npz: No such file or directory (os error 2)"),
        "{line}"
    );
}

#[test]
fn rays_that_cannot_hit_are_misses_not_errors() {
    let s = Scene::new();
    let tiny = f32::MIN_POSITIVE / 4.0;
    let o = Vec3::new(0.2, 0.2, -1.0);
    let rays = [
        Ray::new(o, Vec3::new(f32::NAN, 0.0, 1.0)),
        Ray::new(o, Vec3::new(0.0, 0.0, f32::INFINITY)),
        Ray::new(o, Vec3::ZERO),
        Ray::new(o, Vec3::new(0.0, 0.0, tiny)),
        Ray::new(o, Vec3::Z).with_interval(5.0, 1.0),
        Ray::new(o, Vec3::Z).with_interval(f32::NAN, 5.0),
        Ray::new(o, Vec3::Z).with_interval(-10.0, 10.0),
    ];
    let rays_path = s.path("odd.npz");
    ray_file::write_rays(&rays_path, &rays, hbv::atomic_file::Replace::Always).unwrap();
    let out = s.path("hits.npz");
    let output = hbv(&[
        OsStr::new("trace"),
        s.path("tetra.obj").as_os_str(),
        OsStr::new("--rays"),
        rays_path.as_os_str(),
        OsStr::new("--out"),
        out.as_os_str(),
    ]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let hits = hit_file::read_hits(&out).unwrap();
    assert!(hits[..6].iter().all(Option::is_none), "{hits:?}");
    // Negative tmin is a valid interval: the hit in front of the origin at t = 1.
    assert_eq!(hits[6].map(|h| h.t), Some(1.0));
}

#[test]
fn empty_ray_file_gives_an_empty_hit_file() {
    let s = Scene::new();
    let rays = s.write(
        "none.npz",
        npz(&[
            ("origins.npy", npy("<f4", "(0, 3)", &[])),
            ("directions.npy", npy("<f4", "(0, 3)", &[])),
        ]),
    );
    let out = s.path("hits.npz");
    let output = hbv(&[
        OsStr::new("trace"),
        s.path("tetra.obj").as_os_str(),
        OsStr::new("--rays"),
        rays.as_os_str(),
        OsStr::new("--out"),
        out.as_os_str(),
    ]);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(hit_file::read_hits(&out).unwrap().is_empty());
}

// ------------------------------------------------------------------ output files

fn trace_to(s: &Scene, out: &Path, force: bool) -> Output {
    trace_with(s, out, if force { &["--force"] } else { &[] })
}

/// `hbv trace tetra.obj --rays rays.npz --out OUT` and `extra` arguments.
fn trace_with(s: &Scene, out: &Path, extra: &[&str]) -> Output {
    let (mesh, rays) = (s.path("tetra.obj"), s.path("rays.npz"));
    let mut args = vec![
        OsStr::new("trace"),
        mesh.as_os_str(),
        OsStr::new("--rays"),
        rays.as_os_str(),
        OsStr::new("--out"),
        out.as_os_str(),
    ];
    args.extend(extra.iter().map(OsStr::new));
    hbv(&args)
}

#[test]
fn existing_output_is_never_replaced_without_force() {
    let s = Scene::new();
    let out = s.write("hits.npz", "precious");
    let before = s.files();
    let line = one_error_line(&trace_to(&s, &out, false));
    assert!(
        line.ends_with("hits.npz: the output file exists; pass --force to replace it"),
        "{line}"
    );
    assert_eq!(std::fs::read(&out).unwrap(), b"precious");
    assert_eq!(s.files(), before);
    let output = trace_to(&s, &out, true);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert_eq!(hit_file::read_hits(&out).unwrap().len(), 2);
}

#[test]
fn unwritable_output_paths_are_one_line_and_leave_nothing() {
    let s = Scene::new();
    let before = s.files();
    // A folder that does not exist.
    let line = one_error_line(&trace_to(&s, &s.path("no/such/hits.npz"), false));
    assert!(
        line.contains("no/such/hits.npz: directory") && line.ends_with("does not exist"),
        "{line}"
    );
    // A parent that is a file.
    let line = one_error_line(&trace_to(&s, &s.path("tetra.obj/hits.npz"), false));
    assert!(line.ends_with("tetra.obj is not a directory"), "{line}");
    // A path that is a folder.
    std::fs::create_dir(s.path("folder")).unwrap();
    let line = one_error_line(&trace_to(&s, &s.path("folder"), true));
    assert!(
        line.contains("cannot write hits:") && line.contains("folder"),
        "{line}"
    );
    std::fs::remove_dir(s.path("folder")).unwrap();
    assert_eq!(s.files(), before);
}

/// `--out /dev/null` (a device: nothing the user has is replaced) needs no `--force`, and the
/// device stays a device (it was renamed over, as root, before); a link is written through.
#[cfg(unix)]
#[test]
fn devices_are_written_into_and_links_through() {
    use std::os::unix::fs::FileTypeExt;
    let s = Scene::new();
    let null = Path::new("/dev/null");
    if std::fs::metadata(null).is_ok_and(|m| m.file_type().is_char_device()) {
        let output = trace_to(&s, null, false);
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
        assert!(std::fs::metadata(null)
            .unwrap()
            .file_type()
            .is_char_device());
    }
    let target = s.write("kept.npz", "old");
    std::os::unix::fs::symlink("kept.npz", s.path("link.npz")).unwrap();
    let output = trace_to(&s, &s.path("link.npz"), true);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(std::fs::symlink_metadata(s.path("link.npz"))
        .unwrap()
        .file_type()
        .is_symlink());
    assert_eq!(hit_file::read_hits(&target).unwrap().len(), 2);
}

/// A full disk (`/dev/full`) is reported once, with its reason: the zip crate printed "ZipWriter
/// drop failed: Io(Os { code: 28, ... })" before hbv's line, which said only "zip file error: i/o
/// error".
#[cfg(unix)]
#[test]
fn a_full_disk_is_one_line_with_its_reason() {
    use std::os::unix::fs::FileTypeExt;
    let full = Path::new("/dev/full");
    if !std::fs::metadata(full).is_ok_and(|m| m.file_type().is_char_device()) {
        return; // not Linux
    }
    let s = Scene::new();
    let line = one_error_line(&trace_to(&s, full, false));
    assert!(
        line.ends_with(
            "cannot write hits: cannot write /dev/full: writing failed: \
             No space left on device (os error 28)"
        ),
        "{line}"
    );
}

/// A named pipe is written as a stream (it failed with "Illegal seek", after the zip crate's
/// own message): what the reader gets is the whole hit file.
#[cfg(unix)]
#[test]
fn a_named_pipe_gets_the_whole_hit_file() {
    let s = Scene::new();
    let fifo = s.path("hits.fifo");
    let made = Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|status| status.success()) {
        return; // no mkfifo
    }
    let reader = {
        let fifo = fifo.clone();
        std::thread::spawn(move || std::fs::read(fifo).unwrap())
    };
    let output = trace_to(&s, &fifo, false);
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let bytes = reader.join().unwrap();
    let copy = s.write("copy.npz", &bytes);
    let hits = hit_file::read_hits(&copy).unwrap();
    assert_eq!(hits.len(), 2);
    assert!(hits[0].is_some() && hits[1].is_none());
}

/// Plots, images and ray sets that cannot be written are refused before the work, in one line:
/// `build-compare --plot no/such/x.svg` measured for minutes, then failed with the drawing
/// library's debug text ("backend error: Drawing backend error: ..."); `render -o x.jpg` wrote a
/// PNG named `.jpg`.
#[test]
fn outputs_are_refused_before_any_work() {
    let s = Scene::new();
    let before = s.files();
    let at = |name: &str| s.path(name).to_str().unwrap().to_owned();
    let mesh = at("tetra.obj");
    let cases: [(Vec<String>, String); 6] = [
        (
            vec![
                "build-compare".into(),
                mesh.clone(),
                "--plot".into(),
                at("no/such/cost.png"),
            ],
            format!(
                "cannot write the plot: cannot write {}: directory {} does not exist",
                at("no/such/cost.png"),
                at("no/such")
            ),
        ),
        (
            vec![
                "build-compare".into(),
                mesh.clone(),
                "--plot".into(),
                at("cost.svg"),
            ],
            format!(
                "cannot write the plot: cannot write {}: it is written as PNG, so its name \
                 must end in .png",
                at("cost.svg")
            ),
        ),
        (
            vec!["render".into(), "-o".into(), at("no/such/r.png")],
            format!("directory {} does not exist", at("no/such")),
        ),
        (
            vec!["render".into(), "-o".into(), at("r.jpg")],
            "r.jpg: it is written as PNG, so its name must end in .png".into(),
        ),
        (
            vec!["render".into(), "--exr".into(), at("r.png.tmp")],
            "r.png.tmp: it is written as OpenEXR, so its name must end in .exr".into(),
        ),
        (
            vec![
                "bench".into(),
                mesh.clone(),
                "--rays".into(),
                "10".into(),
                "--write-rays".into(),
                at("tetra.obj/rays"),
            ],
            format!(
                "cannot create {}: {mesh} is not a directory",
                at("tetra.obj/rays")
            ),
        ),
    ];
    for (args, reason) in cases {
        // One line on stderr also means no "measured ..." progress line: nothing was measured.
        let output = hbv(&args);
        assert!(output.stdout.is_empty(), "{args:?} ran");
        let line = one_error_line(&output);
        assert!(line.ends_with(&reason), "{args:?}: {line}");
    }
    assert_eq!(s.files(), before);
}

/// Thread and ray counts past what any machine uses are refused at once (tens of thousands of
/// threads took minutes to start; `bench --rays 2^64 - 1` overflowed an allocation).
#[test]
fn absurd_thread_and_ray_counts_are_one_line() {
    let s = Scene::new();
    let (mesh, out) = (s.path("tetra.obj"), s.path("hits.npz"));
    let line = one_error_line(&trace_with(&s, &out, &["--threads", "100000"]));
    assert!(
        line.ends_with("--threads 100000: at most 1024 (0 uses every core)"),
        "{line}"
    );
    assert!(!out.exists());
    for rays in ["18446744073709551615", "4000000000", "0"] {
        let output = hbv(&["bench", mesh.to_str().unwrap(), "--rays", rays]);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{stderr}");
        assert!(
            stderr.contains("expected 1 to 134217728 rays per set"),
            "{stderr}"
        );
    }
}

/// `build-compare --rays 0` measured nothing and printed `± inf` and `-100.00%`; its counts and
/// seed are now checked when the arguments are read, naming the flag and its range.
#[test]
fn build_compare_counts_are_checked_before_any_work() {
    let cases = [
        (
            ["--rays", "0"],
            "'--rays <RAYS>': expected 1 to 134217728 rays per set",
        ),
        (
            ["--rays", "-5"],
            "'--rays <RAYS>': expected 1 to 134217728 rays per set",
        ),
        (
            ["--rays", "134217729"],
            "expected 1 to 134217728 rays per set",
        ),
        (
            ["--seed", "-1"],
            "'--seed <SEED>': expected a whole number from 0 to",
        ),
    ];
    for (args, reason) in cases {
        let mut all = vec!["build-compare"];
        all.extend(args);
        let output = hbv(&all);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(reason), "{args:?}: {stderr}");
        assert!(output.stdout.is_empty(), "{args:?}");
    }
}

/// Every numeric flag of `hbv experiment` is checked when the arguments are read, naming the
/// flag and what it takes. A NaN displacement was blamed on the mesh ("triangle 0 has a
/// coordinate that is not finite") after building its trees; `--lambda 0` and NaN ran. Negative
/// numbers are read as values (not as unknown flags) and refused for what they are.
#[test]
fn experiment_flags_are_checked_before_any_work() {
    let cases: [(&[&str], &str); 13] = [
        (
            &["dynamic", "--displacement", "nan"],
            "expected a finite number from 0 to 10, not NaN",
        ),
        (
            &["dynamic", "--displacement", "inf"],
            "expected a finite number from 0 to 10, not inf",
        ),
        (
            &["dynamic", "--displacement", "-0.1"],
            "expected a finite number from 0 to 10",
        ),
        (
            &["dynamic", "--displacement", "1e30"],
            "expected a finite number from 0 to 10",
        ),
        (
            &["dynamic", "--seed", "-1"],
            "expected a whole number from 0 to 18446744073709551615",
        ),
        (
            &["seed-claims", "--lambda", "0"],
            "expected a finite number from 0.001 to 1024",
        ),
        (
            &["seed-claims", "--lambda", "NaN"],
            "expected a finite number from 0.001 to 1024, not NaN",
        ),
        (
            &["seed-claims", "--lambda", "1e300"],
            "expected a finite number from 0.001 to 1024",
        ),
        (
            &["seed-claims", "--lambda", "-2"],
            "expected a finite number from 0.001 to 1024",
        ),
        (
            &["seed-claims", "--rays", "0"],
            "expected 1 to 134217728 rays per set",
        ),
        (
            &["seed-claims", "--rays", "-5"],
            "expected 1 to 134217728 rays per set",
        ),
        (&["seed-claims", "--repeat", "-1"], "-1 is not in 1..="),
        (
            &["seed-claims", "--ray-seed", "-3"],
            "expected a whole number from 0 to",
        ),
    ];
    for (args, reason) in cases {
        let mut all = vec!["experiment"];
        all.extend(args);
        let output = hbv(&all);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{args:?}: {stderr}");
        let flag = args[1];
        let value = args[2];
        assert!(
            stderr.starts_with(&format!("error: invalid value '{value}' for '{flag} <")),
            "{args:?}: {stderr}"
        );
        assert!(stderr.contains(reason), "{args:?}: {stderr}");
        assert!(output.stdout.is_empty(), "{args:?} ran");
    }
}

/// A negative number given to any numeric flag of any command is refused for its value, naming
/// the flag (it was read as an unknown flag: `unexpected argument '-5' found`).
#[test]
fn negative_numbers_are_refused_as_values_of_every_command() {
    let cases: &[&[&str]] = &[
        &["bench", "--rays", "-5"],
        &["bench", "--threads", "-1"],
        &["bench", "--repeat", "-2"],
        &["trace", "--threads", "-2", "mesh.ply", "rays.npz"],
        &["render", "--width", "-3"],
        &["info", "--seed", "-1"],
        &["info", "--leaf-size", "-4"],
        &["build-compare", "--rays", "-7"],
    ];
    for args in cases {
        let output = hbv(args);
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(output.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(
            stderr.starts_with(&format!(
                "error: invalid value '{}' for '{} <",
                args[2], args[1]
            )),
            "{args:?}: {stderr}"
        );
        assert!(output.stdout.is_empty(), "{args:?} ran");
    }
}

#[cfg(unix)]
#[test]
fn read_only_output_folder_is_one_line_unless_privileged() {
    use std::os::unix::fs::PermissionsExt;
    let s = Scene::new();
    let locked = s.path("locked");
    std::fs::create_dir(&locked).unwrap();
    std::fs::set_permissions(&locked, std::fs::Permissions::from_mode(0o555)).unwrap();
    if std::fs::write(locked.join("probe"), "x").is_ok() {
        return; // root: permissions do not apply
    }
    let line = one_error_line(&trace_to(&s, &locked.join("hits.npz"), false));
    assert!(
        line.contains("locked/hits.npz: cannot create a temporary file"),
        "{line}"
    );
    assert!(line.ends_with("Permission denied (os error 13)"), "{line}");
    assert_eq!(std::fs::read_dir(&locked).unwrap().count(), 0);
}

// ------------------------------------------------------------------ what the fuzzers found

/// Every `.npz` in `tests/bad_input_cases/` once made the ray reader panic or allocate without
/// bound; each must now read or fail with an error naming the file.
#[test]
fn fuzz_regressions() {
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/bad_input_cases");
    let Ok(entries) = std::fs::read_dir(&folder) else {
        return;
    };
    for entry in entries {
        let path = entry.unwrap().path();
        if path.extension() != Some(OsStr::new("npz")) {
            continue;
        }
        if let Err(e) = ray_file::read_rays(&path) {
            let m = e.to_string();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            assert!(m.contains(&name) && !m.contains('\n'), "{m}");
        }
    }
}
