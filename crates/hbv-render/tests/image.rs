//! The built-in Cornell box rendered small: compared with the reference image in the repository,
//! and identical whichever layout, builder, thread count, structure per ray kind (BVH or uniform
//! grid) and cache setting traced it; traced as a two-level scene, identical with the caches on
//! or off.
//!
//! Tolerance against the reference (`tests/reference/cornell_64x48.png`, made by this test with
//! `HBV_UPDATE_REFERENCE=1`): mean absolute difference at most 0.5 (of 255) per channel, and at
//! most 1% of the pixels differing by more than 8 in any channel: rounding of transcendental
//! functions may differ between platforms and move a few edge pixels; the image must not move.

use std::path::PathBuf;
use std::sync::Arc;

use hbv::bvh::build::{
    BinnedSahBuilder, BinnedSahConfig, Builder, InsertionBuilder, InsertionConfig, LbvhBuilder,
    LbvhConfig, MedianBuilder, MedianConfig, SweepSahBuilder, SweepSahConfig,
};
use hbv::bvh::layout::{OrderedLayout, RecursiveLayout, SkipLayout, Wide4Layout, Wide8Layout};
use hbv::bvh::BuildTree;
use hbv::grid::{GridConfig, UniformGrid};
use hbv::{Accelerator, BruteForce, TriangleMesh};
use hbv_render::image_output::pass_image;
use hbv_render::{render, Frame, Pass, QueryCacheConfig, RenderConfig, Scene, SceneTracer};

const WIDTH: u32 = 64;
const HEIGHT: u32 = 48;
const SPP: u32 = 2;

fn small_cornell_box() -> Scene {
    let mut scene = Scene::cornell_box();
    scene.settings.width = WIDTH;
    scene.settings.height = HEIGHT;
    scene.settings.spp = SPP;
    scene
}

fn render_with(scene: &Scene, accelerator: Arc<dyn Accelerator>, threads: usize) -> Frame {
    let tracer = SceneTracer::new(accelerator.clone(), accelerator);
    render_traced(scene, &tracer, threads)
}

fn render_traced(scene: &Scene, tracer: &SceneTracer, threads: usize) -> Frame {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(|| render(scene, tracer, &RenderConfig::default()))
}

fn wide8(scene: &Scene) -> Arc<dyn Accelerator> {
    let tree = BinnedSahBuilder::new(BinnedSahConfig::default()).build(scene.flat_mesh());
    Arc::new(Wide8Layout::new(&tree, scene.flat_mesh()))
}

fn reference_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/reference/cornell_64x48.png")
}

#[test]
fn cornell_box_matches_the_reference_image() {
    let scene = small_cornell_box();
    let frame = render_with(&scene, wide8(&scene), 2);
    let image = pass_image(&frame.film, Pass::Beauty);
    if std::env::var_os("HBV_UPDATE_REFERENCE").is_some() {
        std::fs::write(reference_path(), image.to_png().unwrap()).unwrap();
    }
    let reference = image::open(reference_path())
        .expect("the reference image is in the repository")
        .to_rgb8();
    assert_eq!((reference.width(), reference.height()), (WIDTH, HEIGHT));
    let diffs: Vec<u32> = reference
        .as_raw()
        .iter()
        .zip(&image.pixels)
        .map(|(&a, &b)| (a as i32 - b as i32).unsigned_abs())
        .collect();
    let mean = diffs.iter().sum::<u32>() as f64 / diffs.len() as f64;
    let far_pixels = diffs.chunks(3).filter(|c| c.iter().any(|&d| d > 8)).count();
    assert!(mean <= 0.5, "mean difference {mean:.3} of 255");
    assert!(
        far_pixels * 100 <= (WIDTH * HEIGHT) as usize,
        "{far_pixels} pixels differ by more than 8 of 255"
    );
    // Not a blank image: the box is lit, the walls coloured.
    assert!(image.pixels.iter().map(|&c| c as u64).sum::<u64>() > 64 * 48 * 3 * 40);
    assert!(
        frame.stats.rays.iter().all(|&n| n > 0),
        "every ray kind is cast"
    );
}

#[test]
fn image_is_identical_for_every_layout_builder_and_thread_count() {
    let scene = small_cornell_box();
    let expected = render_with(&scene, wide8(&scene), 1).film.radiance;
    let mesh: &TriangleMesh = scene.flat_mesh();
    let trees: Vec<(&str, BuildTree)> = vec![
        (
            "insertion",
            InsertionBuilder::new(InsertionConfig::default()).build(mesh),
        ),
        (
            "binned-sah",
            BinnedSahBuilder::new(BinnedSahConfig::default()).build(mesh),
        ),
        (
            "sweep-sah",
            SweepSahBuilder::new(SweepSahConfig::default()).build(mesh),
        ),
        (
            "median",
            MedianBuilder::new(MedianConfig::default()).build(mesh),
        ),
        ("lbvh", LbvhBuilder::new(LbvhConfig::default()).build(mesh)),
    ];
    let mut structures: Vec<(String, Arc<dyn Accelerator>)> =
        vec![("brute force".into(), Arc::new(BruteForce::new(mesh)))];
    for (name, tree) in &trees {
        structures.push((
            format!("{name} recursive"),
            Arc::new(RecursiveLayout::new(tree, mesh)),
        ));
        structures.push((
            format!("{name} wide4"),
            Arc::new(Wide4Layout::new(tree, mesh)),
        ));
    }
    let tree = &trees[1].1;
    structures.push(("skip".into(), Arc::new(SkipLayout::new(tree, mesh))));
    structures.push(("ordered".into(), Arc::new(OrderedLayout::new(tree, mesh))));
    for (threads, (name, accelerator)) in [1, 3].iter().cycle().zip(structures) {
        let film = render_with(&scene, accelerator, *threads).film;
        // Bit for bit: the same hits, the same samples, the same sums.
        assert!(
            film.radiance == expected,
            "{name} on {threads} threads renders a different image"
        );
    }
}

#[test]
fn image_is_identical_for_grid_bvh_or_two_level_scene_with_caches_on_or_off() {
    let scene = small_cornell_box();
    let bvh = wide8(&scene);
    let expected = render_traced(
        &scene,
        &SceneTracer::new(bvh.clone(), bvh.clone()).with_caches(QueryCacheConfig::none()),
        1,
    );
    let grid: Arc<dyn Accelerator> =
        Arc::new(UniformGrid::new(scene.flat_mesh(), GridConfig::default()));
    let unboxed: Arc<dyn Accelerator> = Arc::new(UniformGrid::new(
        scene.flat_mesh(),
        GridConfig {
            mailbox: false,
            ..GridConfig::default()
        },
    ));
    // The two-level scene is compared with its own uncached picture (its placement rounds
    // apart from the flattened scene's, so the two may differ at grazing edges).
    let two_level = SceneTracer::two_level(Arc::new(scene.two_level(Default::default())));
    let two_level_expected = render_traced(
        &scene,
        &two_level.clone().with_caches(QueryCacheConfig::none()),
        1,
    );
    let flat = |primary: &Arc<dyn Accelerator>, shadow: &Arc<dyn Accelerator>| {
        (SceneTracer::new(primary.clone(), shadow.clone()), &expected)
    };
    let tracers = [
        ("grid/grid", flat(&grid, &grid)),
        ("grid/bvh", flat(&grid, &bvh)),
        ("bvh/grid", flat(&bvh, &grid)),
        ("bvh/bvh", flat(&bvh, &bvh)),
        ("unmailboxed grid", flat(&unboxed, &unboxed)),
        ("two-level", (two_level, &two_level_expected)),
    ];
    let caches = [
        ("no caches", QueryCacheConfig::none()),
        ("default caches", QueryCacheConfig::default()),
        (
            "secondary caches too",
            QueryCacheConfig {
                secondary: true,
                ..QueryCacheConfig::default()
            },
        ),
        (
            "a shadow cache per light sample",
            QueryCacheConfig {
                shadow_per_sample: true,
                ..QueryCacheConfig::default()
            },
        ),
    ];
    let mut threads = [1, 3].iter().cycle();
    for (name, (tracer, expected)) in &tracers {
        for (cache_name, cache) in caches {
            let tracer = tracer.clone().with_caches(cache);
            let threads = *threads.next().unwrap();
            let frame = render_traced(&scene, &tracer, threads);
            assert!(
                frame.film.radiance == expected.film.radiance,
                "{name} with {cache_name} on {threads} threads renders a different image"
            );
            assert_eq!(
                frame.stats.rays, expected.stats.rays,
                "{name}, {cache_name}"
            );
            for (k, c) in frame.stats.cache.iter().enumerate() {
                let cached = match k {
                    0 => cache.primary,
                    1 | 2 => cache.secondary,
                    _ => cache.shadow,
                };
                let lookups = c.hits + c.misses;
                assert_eq!(lookups, if cached { frame.stats.rays[k] } else { 0 });
            }
            // Every query counted its work, cached or not, on either structure.
            let work = frame.stats.total_work();
            assert_eq!(work.rays, frame.stats.total_rays(), "{name}, {cache_name}");
            assert!(work.triangles_tested > 0, "{name}, {cache_name}");
        }
    }
}
