//! The film: what each pixel of a frame holds, for every pass.

use glam::Vec3;
use hbv::TraversalStats;

/// A pass of the film that can be written as an image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Pass {
    /// The rendered image (linear radiance, sRGB in PNG files).
    Beauty,
    /// Distance to the first hit of the pixel's first sample.
    Depth,
    /// Shading normal at that hit, turned towards the camera.
    Normal,
    /// Triangle id (in the scene's merged mesh) of that hit.
    Prim,
    /// Heatmap: nodes visited per sample, summed over every ray of the pixel.
    Nodes,
    /// Heatmap: triangles tested per sample, summed over every ray of the pixel.
    Triangles,
}

impl Pass {
    /// Every pass, in the order above.
    pub const ALL: [Pass; 6] = [
        Pass::Beauty,
        Pass::Depth,
        Pass::Normal,
        Pass::Prim,
        Pass::Nodes,
        Pass::Triangles,
    ];

    /// The pass's name on the command line and in file names.
    pub fn name(self) -> &'static str {
        match self {
            Pass::Beauty => "beauty",
            Pass::Depth => "depth",
            Pass::Normal => "normal",
            Pass::Prim => "prim",
            Pass::Nodes => "nodes",
            Pass::Triangles => "triangles",
        }
    }

    /// Whether the pass needs the traversal work counted.
    pub fn needs_work_counted(self) -> bool {
        matches!(self, Pass::Nodes | Pass::Triangles)
    }
}

/// One value per pixel and pass, rows from the top, `index = y · width + x`.
#[derive(Clone, Debug, PartialEq)]
pub struct Film {
    pub width: u32,
    pub height: u32,
    /// Mean linear radiance of the pixel's samples.
    pub radiance: Vec<Vec3>,
    /// Infinite where the first sample missed.
    pub depth: Vec<f32>,
    /// Zero where the first sample missed.
    pub normal: Vec<Vec3>,
    /// `u32::MAX` where the first sample missed.
    pub prim: Vec<u32>,
    /// Work of every query of the pixel, divided by the samples per pixel; zero unless counted.
    pub nodes_visited: Vec<f32>,
    pub triangles_tested: Vec<f32>,
}

/// What the integrator found for one pixel.
#[derive(Clone, Copy, Debug)]
pub struct PixelValue {
    pub radiance: Vec3,
    pub depth: f32,
    pub normal: Vec3,
    pub prim: u32,
    pub work: TraversalStats,
}

impl Film {
    /// A film of `width × height` black pixels.
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        Film {
            width,
            height,
            radiance: vec![Vec3::ZERO; n],
            depth: vec![f32::INFINITY; n],
            normal: vec![Vec3::ZERO; n],
            prim: vec![u32::MAX; n],
            nodes_visited: vec![0.0; n],
            triangles_tested: vec![0.0; n],
        }
    }

    /// Stores pixel `index`, whose work was done over `spp` samples.
    pub fn set(&mut self, index: usize, value: &PixelValue, spp: u32) {
        self.radiance[index] = value.radiance;
        self.depth[index] = value.depth;
        self.normal[index] = value.normal;
        self.prim[index] = value.prim;
        self.nodes_visited[index] = value.work.nodes_visited as f32 / spp as f32;
        self.triangles_tested[index] = value.work.triangles_tested as f32 / spp as f32;
    }
}
