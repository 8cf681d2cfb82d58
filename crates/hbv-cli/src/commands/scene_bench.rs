//! `hbv bench SCENE.glb`: rays per second of a glTF scene's two-level BVH, for every layout of
//! its meshes, on the ray sets `hbv bench` makes for a mesh (made here on the scene's flattened
//! triangles), closest and any hit, on one thread and on all. A saved scene (`SCENE.hbv`) is
//! measured in the one layout its file records.

use std::path::Path;

use anyhow::bail;
use hbv::bvh::build::BuilderKind;
use hbv::bvh::layout::{LayoutKind, LayoutOptions};
use hbv::geometry::Ray;
use hbv::scene::SceneRay;
use hbv::{Scene, TraversalStats};
use hbv_cli::output_check::replace_policy;
use hbv_cli::ray_sets::{camera_image_size, RaySet, Stage};

use super::bench::{
    count_sampled, measure, requested_layouts, thread_pools, timed_hits, timed_occlusion,
    write_ray_sets, BenchArgs, LayoutReport, Measured, Query, Report, SceneFacts,
};
use super::build_args::{load_scene_file, AccelName, SceneSource};

impl Measured for Scene {
    type Ray = SceneRay;

    fn answer(&self, rays: &[SceneRay], query: Query) -> (f64, usize) {
        match query {
            Query::Closest => timed_hits(|| self.intersect_batch(rays)),
            Query::Occluded => timed_occlusion(|| self.occluded_batch(rays)),
        }
    }

    /// Counted by [`Scene::intersect_counted`] and [`Scene::occluded_counted`]: the nodes,
    /// boxes and triangles of the instances' meshes, each instance entered as one node visited
    /// (the top level's own boxes are not counted).
    fn count_tests(&self, rays: &[SceneRay], query: Query, count: usize) -> TraversalStats {
        count_sampled(rays, count, |ray, stats| match query {
            Query::Closest => {
                self.intersect_counted(ray, stats);
            }
            Query::Occluded => {
                self.occluded_counted(ray, stats);
            }
        })
    }
}

/// Loads the scene once per requested layout (each mesh built by `--builder`, binned SAH unless
/// told; a saved scene once, as saved) and measures it on the ray sets; or writes the sets with
/// `--write-rays`.
pub fn run(path: &Path, source: SceneSource, args: &BenchArgs) -> anyhow::Result<()> {
    if args.accel == AccelName::Grid {
        bail!(
            "{}: --accel grid takes a mesh; a scene is measured with its two-level BVH \
             (--accel bvh)",
            path.display()
        );
    }
    let layout_flags: &[&str] = if args.layouts.is_empty() {
        &[]
    } else {
        &["--layout"]
    };
    source.check_options(path, &args.build, layout_flags)?;
    let build = args.build.or_builder(BuilderKind::BinnedSah);
    let layouts = match source {
        SceneSource::Gltf => requested_layouts(&args.layouts),
        // One load; the layout passed to it is unused (the file says which).
        SceneSource::Saved => vec![LayoutKind::Wide8],
    };
    let described = match source {
        SceneSource::Gltf => format!("each mesh: {}; top level: binned SAH", build.describe()),
        SceneSource::Saved => source.describe(&build, layouts[0]),
    };
    let structure_of =
        |layout| build.scene_structure(BuilderKind::BinnedSah, layout, LayoutOptions::default());
    let pools = thread_pools(args.threads)?;
    let all_threads = pools.last().expect("at least one pool");
    let (first, load_seconds) =
        all_threads.install(|| load_scene_file(path, source, structure_of(layouts[0])))?;
    let flat = first
        .flattened()
        .map_err(|e| anyhow::anyhow!("{}: cannot flatten the scene: {e}", path.display()))?;
    if flat.mesh.triangle_count() == flat.mesh.degenerate_count() {
        bail!(
            "{} has no triangle of non-zero area: there is no surface to shoot rays from",
            path.display()
        );
    }
    let sets: Vec<(RaySet, Vec<Ray>)> = RaySet::ALL
        .iter()
        .map(|&set| (set, set.generate(&flat.mesh, args.rays, args.ray_seed)))
        .collect();
    if let Some(dir) = &args.write_rays {
        return write_ray_sets(dir, &sets, replace_policy(args.force));
    }
    let light = Stage::new(&flat.mesh.bounds()).light.to_array();
    drop(flat);
    // Ray files carry no masks: every ray sees every instance.
    let scene_sets: Vec<(RaySet, Vec<SceneRay>)> = sets
        .into_iter()
        .map(|(set, rays)| (set, rays.into_iter().map(SceneRay::from).collect()))
        .collect();

    let summary = first.summary();
    let mut first = Some((first, load_seconds));
    let mut reports = Vec::new();
    let mut results = Vec::new();
    for layout in layouts {
        let (scene, seconds) = match first.take() {
            Some(loaded) => loaded,
            None => all_threads.install(|| load_scene_file(path, source, structure_of(layout)))?,
        };
        let report = LayoutReport {
            layout: match source {
                SceneSource::Gltf => layout.to_string(),
                SceneSource::Saved => "saved".into(),
            },
            memory_bytes: scene.summary().memory_bytes(),
            layout_seconds: seconds,
        };
        results.extend(measure(&scene, &report, &scene_sets, &pools, args));
        reports.push(report);
    }

    let report = Report {
        mesh: path.display().to_string(),
        triangles: summary.triangles_stored,
        builder: described,
        load_seconds,
        build_seconds: None,
        scene: Some(SceneFacts {
            meshes: summary.meshes.len(),
            instances: summary.live_instances,
            triangles_seen: summary.triangles_seen,
        }),
        rays_per_set: args.rays,
        ray_seed: args.ray_seed,
        camera: camera_image_size(args.rays).into(),
        light,
        repeat: args.repeat,
        thread_counts: pools.iter().map(|p| p.current_num_threads()).collect(),
        layouts: reports,
        results,
    };
    report.print(args.json)
}
