//! The kinds of rays a Whitted renderer casts, and what it counts about each kind.

use std::ops::AddAssign;

use hbv::cache::CacheStats;
use hbv::TraversalStats;

/// Why a ray was cast. Every query of the renderer names its kind, so that structures and caches
/// can be chosen per kind and the work of each kind is counted apart.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum RayKind {
    /// From the camera through a pixel.
    Primary,
    /// Off a mirror, or the reflected part of glass.
    Reflected,
    /// Through glass (refracted).
    Transmitted,
    /// From a surface point towards sample of light `light` (its index in the scene).
    Shadow { light: u32 },
}

impl RayKind {
    /// The four kinds, in the order of [`RayStats`]' arrays.
    pub const NAMES: [&'static str; 4] = ["primary", "reflected", "transmitted", "shadow"];

    /// Index into [`RayStats`]' per-kind arrays (all lights' shadow rays share one slot).
    pub fn index(self) -> usize {
        match self {
            RayKind::Primary => 0,
            RayKind::Reflected => 1,
            RayKind::Transmitted => 2,
            RayKind::Shadow { .. } => 3,
        }
    }
}

/// Rays cast, work done (when counted) and time spent in queries (when timed), per ray kind,
/// indexed by [`RayKind::index`].
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct RayStats {
    pub rays: [u64; 4],
    /// Nodes visited and boxes and triangles tested; zero unless work is counted.
    pub work: [TraversalStats; 4],
    /// Nanoseconds inside the accelerators' queries; zero unless queries are timed.
    pub query_nanos: [u64; 4],
    /// Object cache hits and misses (all lights' shadow caches together); zero for kinds that
    /// bypass the caches.
    pub cache: [CacheStats; 4],
    /// Shadow rays found blocked (the most a shadow cache could hit).
    pub shadow_blocked: u64,
}

impl RayStats {
    /// All rays of every kind.
    pub fn total_rays(&self) -> u64 {
        self.rays.iter().sum()
    }

    /// The work of every kind together.
    pub fn total_work(&self) -> TraversalStats {
        let mut all = TraversalStats::default();
        for w in self.work {
            all += w;
        }
        all
    }
}

impl AddAssign for RayStats {
    fn add_assign(&mut self, o: Self) {
        for k in 0..4 {
            self.rays[k] += o.rays[k];
            self.work[k] += o.work[k];
            self.query_nanos[k] += o.query_nanos[k];
            self.cache[k] += o.cache[k];
        }
        self.shadow_blocked += o.shadow_blocked;
    }
}
