//! Rendering a frame: square tiles traced in parallel, each pixel independent of the others.

use std::sync::atomic::{AtomicU64, Ordering};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use crate::film::{Film, PixelValue};
use crate::integrator::Whitted;
use crate::progress::RenderProgress;
use crate::ray_kind::RayStats;
use crate::sampler::PixelSampler;
use crate::scene::Scene;
use crate::tracer::SceneTracer;

/// How to render (what to render is in the scene's [`RenderSettings`](crate::RenderSettings)).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct RenderConfig {
    /// Side of the square tiles handed to threads, in pixels.
    pub tile_size: u32,
    /// Use the counted queries: tests per ray, and the node and triangle heatmaps.
    pub count_work: bool,
    /// Time every query, for the share of time of each ray kind (costs two clock reads a ray).
    pub time_queries: bool,
    /// Hide the progress bar (it is hidden anyway when stderr is not a terminal).
    pub quiet: bool,
}

impl Default for RenderConfig {
    fn default() -> Self {
        RenderConfig {
            tile_size: 16,
            count_work: true,
            time_queries: false,
            quiet: true,
        }
    }
}

/// A rendered frame: the film, the rays cast by kind, and the wall-clock time of the render.
#[derive(Clone, Debug)]
pub struct Frame {
    pub film: Film,
    pub stats: RayStats,
    pub seconds: f64,
}

/// Renders `scene` through `tracer`, on the current rayon pool.
///
/// Sample `s` of pixel `(x, y)` draws its random numbers from [`PixelSampler`] seeded with
/// `y · width + x` and runs entirely on one thread, and the film is assembled in pixel order, so
/// the image does not depend on the number of threads or the order tiles finish in. Each tile
/// gets fresh object caches ([`SceneTracer::tally`]: over the two-level scene, or over the
/// flattened scene's mesh, the mesh a flat tracer's accelerators must come from); caches change
/// the work, never a hit. With one sample per pixel the primary ray goes through the pixel's
/// centre; with more, each sample is jittered uniformly inside the pixel.
pub fn render(scene: &Scene, tracer: &SceneTracer, config: &RenderConfig) -> Frame {
    let settings = scene.settings;
    let (width, height) = (settings.width, settings.height);
    let tile = config.tile_size.max(1);
    let tiles: Vec<(u32, u32)> = (0..height.div_ceil(tile))
        .flat_map(|ty| (0..width.div_ceil(tile)).map(move |tx| (tx * tile, ty * tile)))
        .collect();
    let camera = scene.camera.rays(width, height);
    let integrator = Whitted::new(scene, tracer);
    let progress = RenderProgress::new(tiles.len() as u64, config.quiet);
    let rays_so_far = AtomicU64::new(0);
    let start = Instant::now();

    let done: Vec<(Vec<(usize, PixelValue)>, RayStats)> = tiles
        .par_iter()
        .map(|&(x0, y0)| {
            let mut tally = tracer.tally(scene, config.count_work, config.time_queries);
            let mut pixels = Vec::with_capacity((tile * tile) as usize);
            for y in y0..(y0 + tile).min(height) {
                for x in x0..(x0 + tile).min(width) {
                    let index = y as usize * width as usize + x as usize;
                    let mut sampler = PixelSampler::new(index as u64);
                    let mut value = PixelValue {
                        radiance: Vec3::ZERO,
                        depth: f32::INFINITY,
                        normal: Vec3::ZERO,
                        prim: u32::MAX,
                        work: Default::default(),
                    };
                    for s in 0..settings.spp {
                        let (dx, dy) = if settings.spp == 1 {
                            (0.5, 0.5)
                        } else {
                            (sampler.next_f32(), sampler.next_f32())
                        };
                        let ray = camera.ray(x, y, dx, dy);
                        let (radiance, seen) = integrator.primary(&ray, &mut sampler, &mut tally);
                        value.radiance += radiance;
                        if let (0, Some(seen)) = (s, seen) {
                            value.depth = seen.depth;
                            value.normal = seen.normal;
                            value.prim = seen.face as u32;
                        }
                    }
                    value.radiance /= settings.spp as f32;
                    value.work = tally.take_pixel_work();
                    pixels.push((index, value));
                }
            }
            let stats = tally.into_stats();
            let rays =
                rays_so_far.fetch_add(stats.total_rays(), Ordering::Relaxed) + stats.total_rays();
            progress.tile_done(rays as f64 / start.elapsed().as_secs_f64().max(1e-9));
            (pixels, stats)
        })
        .collect();
    let seconds = start.elapsed().as_secs_f64();
    progress.finish();

    let mut film = Film::new(width, height);
    let mut stats = RayStats::default();
    for (pixels, tile_stats) in &done {
        for (index, value) in pixels {
            film.set(*index, value, settings.spp);
        }
        stats += *tile_stats;
    }
    Frame {
        film,
        stats,
        seconds,
    }
}
