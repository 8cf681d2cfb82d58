//! Traces a ray file on a glTF scene (two-level: [`Scene`]) or on a mesh (its own BVH), one
//! ray at a time on one thread, writes the answers as a hit file of `docs/RAYS.md` (with
//! `instance` and `normal` for a scene) and prints the rate.
//!
//! ```text
//! cargo run --release -p hbv-cli --example scene_trace -- SCENE.glb|MESH.ply RAYS.npz
//!     [--out HITS.npz] [--occluded] [--repeat N] [--batch]
//! ```
//!
//! Closest hit by default ([`Scene::intersect`], or the mesh's wide-8 layout's
//! [`Accelerator::intersect`]); `--occluded` answers any hit ([`Scene::occluded`],
//! [`Accelerator::occluded`]) and writes `occluded`. The set is traced `N` times (default 5);
//! printed: the median and the best rate in Mrays/s and the hit count, one JSON line. For
//! BENCHMARKS.md, "Scenes against Embree" (Embree's loop is `embree_oracle.py bench`, one
//! `rtcIntersect1` / `rtcOccluded1` call a ray). `--batch` traces the set as one batch
//! ([`Scene::intersect_batch`] / [`Scene::occluded_batch`], or the mesh's
//! [`Accelerator::intersect_batch`] / [`Accelerator::occluded_batch`]) on a pool of one thread.

use std::fs::File;
use std::path::PathBuf;
use std::time::Instant;

use hbv::bvh::build::{BuilderKind, BuilderOptions};
use hbv::bvh::layout::{AnyLayout, LayoutKind, LayoutOptions};
use hbv::scene::{Scene, SceneHit, SceneRay};
use hbv::{Accelerator, Hit, TriangleMesh};
use ndarray::{Array1, Array2};
use ndarray_npy::NpzWriter;

/// What is traced: a scene of instances, or one mesh by its own layout.
enum Target {
    Scene(Scene),
    Mesh(AnyLayout),
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut positional = Vec::new();
    let (mut out, mut occluded, mut repeat) = (None::<PathBuf>, false, 5usize);
    let mut batch = false;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--out" => out = Some(args.next().ok_or("--out needs a path")?.into()),
            "--occluded" => occluded = true,
            "--batch" => batch = true,
            "--repeat" => repeat = args.next().ok_or("--repeat needs a number")?.parse()?,
            _ => positional.push(PathBuf::from(arg)),
        }
    }
    let [input, rays_path] = positional.as_slice() else {
        return Err(
            "usage: scene_trace SCENE.glb|MESH.ply RAYS.npz [--out HITS.npz] \
                    [--occluded] [--repeat N] [--batch]"
                .into(),
        );
    };
    let repeat = repeat.max(1);
    let is_scene = input
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("glb") || e.eq_ignore_ascii_case("gltf"));
    let start = Instant::now();
    let target = if is_scene {
        let mut scene = Scene::load(input)?;
        scene.build();
        Target::Scene(scene)
    } else {
        let mesh = TriangleMesh::load(input)?;
        let tree = BuilderKind::BinnedSah.build(&mesh, &BuilderOptions::default());
        Target::Mesh(LayoutKind::Wide8.lay_out(&tree, &mesh, &LayoutOptions::default()))
    };
    let build_s = start.elapsed().as_secs_f64();
    let rays = hbv_cli::ray_file::read_rays(rays_path)?;
    let scene_rays: Vec<SceneRay> = rays.iter().map(|r| SceneRay::new(*r)).collect();

    let one_thread = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut rates = Vec::with_capacity(repeat);
    let mut closest: Vec<Option<SceneHit>> = Vec::new();
    let mut any: Vec<bool> = Vec::new();
    for _ in 0..repeat {
        let start = Instant::now();
        match (&target, occluded, batch) {
            (Target::Scene(s), false, false) => {
                closest = scene_rays.iter().map(|r| s.intersect(r)).collect()
            }
            (Target::Scene(s), true, false) => {
                any = scene_rays.iter().map(|r| s.occluded(r)).collect()
            }
            (Target::Mesh(m), false, false) => {
                closest = rays
                    .iter()
                    .map(|r| m.intersect(r).map(as_scene_hit))
                    .collect()
            }
            (Target::Mesh(m), true, false) => any = rays.iter().map(|r| m.occluded(r)).collect(),
            (Target::Scene(s), false, true) => {
                closest = one_thread.install(|| s.intersect_batch(&scene_rays))
            }
            (Target::Scene(s), true, true) => {
                any = one_thread.install(|| s.occluded_batch(&scene_rays))
            }
            (Target::Mesh(m), false, true) => {
                closest = one_thread
                    .install(|| m.intersect_batch(&rays))
                    .into_iter()
                    .map(|h| h.map(as_scene_hit))
                    .collect()
            }
            (Target::Mesh(m), true, true) => any = one_thread.install(|| m.occluded_batch(&rays)),
        }
        rates.push(rays.len() as f64 / start.elapsed().as_secs_f64() / 1e6);
    }
    rates.sort_by(f64::total_cmp);
    let hits = if occluded {
        any.iter().filter(|&&o| o).count()
    } else {
        closest.iter().flatten().count()
    };
    println!(
        "{{\"input\": {:?}, \"rays\": {}, \"query\": \"{}\", \"batch\": {batch}, \"build_s\": {build_s:.3}, \
         \"mrays_per_s_median\": {:.4}, \"mrays_per_s_best\": {:.4}, \"hits\": {hits}}}",
        input.display().to_string(),
        rays.len(),
        if occluded { "any hit" } else { "closest hit" },
        rates[repeat / 2],
        rates[repeat - 1]
    );
    if let Some(out) = out {
        let mut npz = NpzWriter::new(File::create(&out)?);
        if occluded {
            npz.add_array("occluded", &Array1::from(any))?;
        } else {
            let n = closest.len();
            let field = |f: &dyn Fn(&SceneHit) -> f32, miss: f32| {
                Array1::from_iter(closest.iter().map(|h| h.as_ref().map_or(miss, f)))
            };
            npz.add_array(
                "hit",
                &Array1::from_iter(closest.iter().map(Option::is_some)),
            )?;
            npz.add_array("t", &field(&|h| h.t, f32::INFINITY))?;
            npz.add_array("u", &field(&|h| h.u, 0.0))?;
            npz.add_array("v", &field(&|h| h.v, 0.0))?;
            let id = |f: &dyn Fn(&SceneHit) -> u32| {
                Array1::from_iter(
                    closest
                        .iter()
                        .map(|h| h.as_ref().map_or(-1, |h| i64::from(f(h)))),
                )
            };
            npz.add_array("prim", &id(&|h| h.prim))?;
            if is_scene {
                npz.add_array("instance", &id(&|h| h.instance))?;
                let normals: Vec<f32> = closest
                    .iter()
                    .flat_map(|h| h.map_or([0.0; 3], |h| h.normal.to_array()))
                    .collect();
                npz.add_array("normal", &Array2::from_shape_vec((n, 3), normals)?)?;
            }
        }
        npz.finish()?;
    }
    Ok(())
}

/// A mesh's hit as a scene's of instance 0 (its normal left zero: not written for meshes).
fn as_scene_hit(hit: Hit) -> SceneHit {
    SceneHit {
        t: hit.t,
        u: hit.u,
        v: hit.v,
        prim: hit.prim,
        instance: 0,
        normal: hbv::glam::Vec3::ZERO,
    }
}
