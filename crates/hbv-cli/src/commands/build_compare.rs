//! `hbv build-compare`: every builder on one table, each tree's predicted cost E[X] against the
//! tests counted on isotropic lines and on real rays.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use hbv::atomic_file::Replace;
use hbv::bvh::layout::RecursiveLayout;
use hbv::bvh::measured_cost::{closest_hit_work, isotropic_lines, tests_per_line};
use hbv::bvh::{expected_tests, sah_cost, SahWeights};
use hbv::geometry::{Aabb, Ray};
use hbv::glam::Vec3;
use hbv::TriangleMesh;
use hbv_cli::output_check::{check_output, replace_policy, OutputFormat};
use hbv_cli::plot::{predicted_vs_measured, LabelledPoint, Series};
use hbv_cli::ray_sets::RaySet;
use rand::{RngExt, SeedableRng};
use rand_pcg::Pcg64Mcg;
use serde::Serialize;

use super::build_args::{load_mesh, BuildArgs};
use super::flag_values::{ray_count, seed};
use super::name_values::builder_kind;
use hbv::bvh::build::BuilderKind;

#[derive(Args)]
pub struct BuildCompareArgs {
    /// Mesh file (.obj, .ply, .gltf, .glb); the built-in scene when omitted.
    pub mesh: Option<PathBuf>,
    /// Isotropic lines, and real rays of each kind, to count tests on (1 to 2^27; none gave
    /// means of 0/0).
    #[arg(long, default_value_t = 200_000, value_parser = ray_count)]
    pub rays: usize,
    /// Builders to compare [default: all].
    #[arg(long = "builder", value_parser = builder_kind())]
    pub builders: Vec<BuilderKind>,
    /// Also skip the reinsertion-optimized variant of each builder.
    #[arg(long)]
    pub no_optimize: bool,
    /// Seed of the lines and rays.
    #[arg(long, default_value_t = 1, value_parser = seed)]
    pub seed: u64,
    /// Print a JSON list of rows instead of the table.
    #[arg(long)]
    pub json: bool,
    /// Print CSV instead of the table.
    #[arg(long, conflicts_with = "json")]
    pub csv: bool,
    /// Draw predicted E[X] against measured tests to this PNG file (its name ends in .png; its
    /// folder must exist).
    #[arg(long)]
    pub plot: Option<PathBuf>,
    /// With --plot: replace the image if it exists (without this, an existing file is an error,
    /// reported before any work).
    #[arg(long, requires = "plot")]
    pub force: bool,
}

/// One row of the table: a builder, optionally optimized, and its tree's costs.
#[derive(Serialize)]
struct Row {
    builder: String,
    optimize: bool,
    build_seconds: f64,
    optimize_seconds: f64,
    nodes: usize,
    leaves: usize,
    depth_max: usize,
    expected_tests: f64,
    sah_cost: f64,
    measured_tests_per_line: f64,
    measured_tests_per_line_std_error: f64,
    /// `measured_tests_per_line / expected_tests - 1`.
    line_relative_error: f64,
    camera_boxes_per_ray: f64,
    camera_triangles_per_ray: f64,
    inside_boxes_per_ray: f64,
    inside_triangles_per_ray: f64,
}

pub fn run(args: &BuildCompareArgs) -> anyhow::Result<()> {
    if let Some(plot) = &args.plot {
        if !args.force && hbv::atomic_file::would_replace(plot) {
            anyhow::bail!(
                "{}: the output file exists; pass --force to replace it",
                plot.display()
            );
        }
        // Before minutes of measuring, not after.
        check_output(plot, Some(OutputFormat::Png)).context("cannot write the plot")?;
    }
    let (mesh, name, _) = load_mesh(args.mesh.as_deref())?;
    let bounds = mesh.bounds();
    let lines = isotropic_lines(&bounds, args.rays, args.seed);
    let camera = RaySet::Primary.generate(&mesh, args.rays, args.seed);
    let inside = inside_rays(&bounds, args.rays, args.seed);

    let builders = if args.builders.is_empty() {
        BuilderKind::ALL.to_vec()
    } else {
        args.builders.clone()
    };
    let mut rows = Vec::new();
    for &builder in &builders {
        for optimize in [false, true] {
            if optimize && args.no_optimize {
                continue;
            }
            let options = BuildArgs {
                builder: Some(builder),
                optimize,
                ..BuildArgs::default()
            };
            rows.push(measure(&mesh, &options, &lines, &camera, &inside));
            if !args.json && !args.csv {
                eprintln!("measured {}", options.describe());
            }
        }
    }

    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
    } else if args.csv {
        print_csv(&rows);
    } else {
        print_table(&name, &mesh, args.rays, &rows);
    }
    if let Some(path) = &args.plot {
        plot(path, replace_policy(args.force), &name, &rows)?;
    }
    Ok(())
}

/// Builds (and optimizes) one tree and counts its tests.
fn measure(
    mesh: &TriangleMesh,
    options: &BuildArgs,
    lines: &[Ray],
    camera: &[Ray],
    inside: &[Ray],
) -> Row {
    let built = options.build_with_report(mesh);
    let tree = &built.tree;
    let shape = tree.shape();
    let layout = RecursiveLayout::new(tree, mesh);
    let expected = expected_tests(tree);
    let per_line = tests_per_line(&layout, lines);
    let per_ray = |rays: &[Ray]| {
        let s = closest_hit_work(&layout, rays);
        (s.boxes_per_ray(), s.triangles_per_ray())
    };
    let (camera_boxes, camera_triangles) = per_ray(camera);
    let (inside_boxes, inside_triangles) = per_ray(inside);
    Row {
        builder: options.builder().name().to_string()
            + if options.optimize { "+optimize" } else { "" },
        optimize: options.optimize,
        build_seconds: built.build_seconds,
        optimize_seconds: built.optimize_seconds,
        nodes: shape.nodes,
        leaves: shape.leaves,
        depth_max: shape.depth_max,
        expected_tests: expected,
        sah_cost: sah_cost(tree, SahWeights::default()),
        measured_tests_per_line: per_line.mean,
        measured_tests_per_line_std_error: per_line.standard_error,
        line_relative_error: if expected > 0.0 {
            per_line.mean / expected - 1.0
        } else {
            0.0
        },
        camera_boxes_per_ray: camera_boxes,
        camera_triangles_per_ray: camera_triangles,
        inside_boxes_per_ray: inside_boxes,
        inside_triangles_per_ray: inside_triangles,
    }
}

/// Rays from uniform points of the box in uniform directions: "random rays inside the scene".
fn inside_rays(bounds: &Aabb, n: usize, seed: u64) -> Vec<Ray> {
    let mut rng = Pcg64Mcg::seed_from_u64(seed ^ 0x1_5eed);
    let extent = bounds.extent();
    (0..n)
        .map(|_| {
            let u = Vec3::new(rng.random(), rng.random(), rng.random());
            let z: f32 = rng.random_range(-1.0..1.0);
            let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
            let r = (1.0 - z * z).max(0.0).sqrt();
            Ray::new(
                bounds.min + extent * u,
                Vec3::new(r * phi.cos(), r * phi.sin(), z),
            )
        })
        .collect()
}

fn print_table(name: &str, mesh: &TriangleMesh, rays: usize, rows: &[Row]) {
    println!("{name}: {} triangles; {rays} isotropic lines, {rays} camera rays, {rays} rays from inside the box", mesh.triangle_count());
    println!(
        "{:<20} {:>8} {:>8} {:>9} {:>5} {:>9} {:>8} {:>17} {:>7} {:>15} {:>15}",
        "builder",
        "build s",
        "opt s",
        "nodes",
        "depth",
        "E[X]",
        "SAH",
        "tests/line ± se",
        "line/E",
        "camera box/tri",
        "inside box/tri"
    );
    for r in rows {
        println!(
            "{:<20} {:>8.3} {:>8.3} {:>9} {:>5} {:>9.2} {:>8.2} {:>10.2} ± {:<4.2} {:>+6.2}% {:>7.1}/{:<7.1} {:>7.1}/{:<7.1}",
            r.builder,
            r.build_seconds,
            r.optimize_seconds,
            r.nodes,
            r.depth_max,
            r.expected_tests,
            r.sah_cost,
            r.measured_tests_per_line,
            r.measured_tests_per_line_std_error,
            100.0 * r.line_relative_error,
            r.camera_boxes_per_ray,
            r.camera_triangles_per_ray,
            r.inside_boxes_per_ray,
            r.inside_triangles_per_ray
        );
    }
}

fn print_csv(rows: &[Row]) {
    println!("builder,optimize,build_seconds,optimize_seconds,nodes,leaves,depth_max,expected_tests,sah_cost,measured_tests_per_line,measured_tests_per_line_std_error,camera_boxes_per_ray,camera_triangles_per_ray,inside_boxes_per_ray,inside_triangles_per_ray");
    for r in rows {
        println!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.builder,
            r.optimize,
            r.build_seconds,
            r.optimize_seconds,
            r.nodes,
            r.leaves,
            r.depth_max,
            r.expected_tests,
            r.sah_cost,
            r.measured_tests_per_line,
            r.measured_tests_per_line_std_error,
            r.camera_boxes_per_ray,
            r.camera_triangles_per_ray,
            r.inside_boxes_per_ray,
            r.inside_triangles_per_ray
        );
    }
}

fn plot(path: &std::path::Path, replace: Replace, name: &str, rows: &[Row]) -> anyhow::Result<()> {
    let series = |label: &str, y: fn(&Row) -> f64| Series {
        name: label.to_string(),
        points: rows
            .iter()
            .map(|r| LabelledPoint {
                label: r.builder.clone(),
                x: r.expected_tests,
                y: y(r),
            })
            .collect(),
    };
    predicted_vs_measured(
        path,
        replace,
        &format!("Predicted against measured tests per ray: {name}"),
        "predicted E[X] (tests per isotropic line)",
        "measured tests per ray",
        &[
            series("isotropic lines, no early exit", |r| {
                r.measured_tests_per_line
            }),
            series("camera rays, closest hit", |r| {
                r.camera_boxes_per_ray + r.camera_triangles_per_ray
            }),
            series("rays from inside, closest hit", |r| {
                r.inside_boxes_per_ray + r.inside_triangles_per_ray
            }),
        ],
    )
}
