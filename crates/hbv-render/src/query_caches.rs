//! Which object caches the renderer's queries go through, and one render thread's caches.

use hbv::cache::{CacheStats, LastHitCache, SceneLastHitCache, SceneShadowCache, ShadowCache};
use hbv::{Accelerator, TriangleMesh};

use crate::ray_kind::RayKind;

/// Which ray kinds go through an object cache (see `hbv::cache`). The caches never change an
/// answer, only the work done to find it, so the image is the same for every setting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct QueryCacheConfig {
    /// A shadow cache per light source and per tile for shadow rays.
    pub shadow: bool,
    /// A last-hit cache per tile for primary rays (coherent: traced in pixel order).
    pub primary: bool,
    /// A last-hit cache per tile for reflected rays and another for transmitted rays. Off by
    /// default: the seed says secondary rays bypass the caches; this exists to measure what a
    /// cache would give them.
    pub secondary: bool,
    /// Diagnostic: a shadow cache per light *sample* (sample `k` of every shading point shares
    /// one) instead of per light, to measure whether rays towards the same part of an area
    /// light are more coherent. Off by default.
    pub shadow_per_sample: bool,
}

impl Default for QueryCacheConfig {
    /// Shadow and primary caches on, secondary rays uncached (the seed's statement).
    fn default() -> Self {
        QueryCacheConfig {
            shadow: true,
            primary: true,
            secondary: false,
            shadow_per_sample: false,
        }
    }
}

impl QueryCacheConfig {
    /// No cache at all: every query goes straight to its accelerator.
    pub fn none() -> Self {
        QueryCacheConfig {
            shadow: false,
            primary: false,
            secondary: false,
            shadow_per_sample: false,
        }
    }

    /// Whether rays of `kind` go through a cache.
    pub fn caches(&self, kind: RayKind) -> bool {
        match kind {
            RayKind::Primary => self.primary,
            RayKind::Reflected | RayKind::Transmitted => self.secondary,
            RayKind::Shadow { .. } => self.shadow,
        }
    }
}

/// An object cache that counts how often its cached triangle answered.
pub trait ObjectCache {
    /// Hits and misses so far.
    fn stats(&self) -> CacheStats;
}

impl ObjectCache for LastHitCache<'_, dyn Accelerator> {
    fn stats(&self) -> CacheStats {
        LastHitCache::stats(self)
    }
}

impl ObjectCache for ShadowCache<'_, dyn Accelerator> {
    fn stats(&self) -> CacheStats {
        ShadowCache::stats(self)
    }
}

impl ObjectCache for SceneLastHitCache<'_> {
    fn stats(&self) -> CacheStats {
        SceneLastHitCache::stats(self)
    }
}

impl ObjectCache for SceneShadowCache<'_> {
    fn stats(&self) -> CacheStats {
        SceneShadowCache::stats(self)
    }
}

/// The caches of one render thread (one tile): a last-hit cache `L` per intersection ray kind
/// that [`QueryCacheConfig`] enables, and a shadow cache `S` per light (or per light sample),
/// made on its first shadow ray. Mutable, unshared state; what the caches test (accelerators
/// and a mesh, or a two-level scene) is shared.
pub struct QueryCaches<'a, L, S> {
    config: QueryCacheConfig,
    /// Makes an empty shadow cache over the shared structure.
    new_shadow: Box<dyn Fn() -> S + 'a>,
    /// Indexed by [`RayKind::index`] (0 primary, 1 reflected, 2 transmitted).
    last_hit: [Option<L>; 3],
    /// Indexed by light, then by sample (one slot unless `shadow_per_sample`).
    shadow: Vec<Vec<Option<S>>>,
}

/// The caches of a tracer over the flattened scene: [`LastHitCache`] and [`ShadowCache`] over
/// its accelerators.
pub type FlatQueryCaches<'a> =
    QueryCaches<'a, LastHitCache<'a, dyn Accelerator>, ShadowCache<'a, dyn Accelerator>>;

/// The caches of a tracer over the two-level scene: [`SceneLastHitCache`] and
/// [`SceneShadowCache`], keyed by `(instance, prim)`.
pub type SceneQueryCaches<'a> = QueryCaches<'a, SceneLastHitCache<'a>, SceneShadowCache<'a>>;

impl<'a> FlatQueryCaches<'a> {
    /// Empty caches over the accelerators a flat tracer uses, built from `mesh`.
    pub fn new(
        config: QueryCacheConfig,
        mesh: &'a TriangleMesh,
        intersection: &'a (dyn Accelerator + 'static),
        shadow: &'a (dyn Accelerator + 'static),
    ) -> Self {
        QueryCaches::with_makers(
            config,
            || LastHitCache::new(intersection, mesh),
            move || ShadowCache::new(shadow, mesh),
        )
    }
}

impl<'a> SceneQueryCaches<'a> {
    /// Empty caches over the two-level scene `scene`.
    pub fn over_scene(config: QueryCacheConfig, scene: &'a hbv::scene::Scene) -> Self {
        QueryCaches::with_makers(
            config,
            || SceneLastHitCache::new(scene),
            move || SceneShadowCache::new(scene),
        )
    }
}

impl<'a, L: ObjectCache, S: ObjectCache> QueryCaches<'a, L, S> {
    /// The last-hit caches `config` enables, made now by `new_last_hit`; shadow caches are
    /// made by `new_shadow` on their first ray.
    fn with_makers(
        config: QueryCacheConfig,
        new_last_hit: impl Fn() -> L,
        new_shadow: impl Fn() -> S + 'a,
    ) -> Self {
        let last_hit = [RayKind::Primary, RayKind::Reflected, RayKind::Transmitted]
            .map(|kind| config.caches(kind).then(&new_last_hit));
        QueryCaches {
            config,
            new_shadow: Box::new(new_shadow),
            last_hit,
            shadow: Vec::new(),
        }
    }

    /// The last-hit cache of an intersection ray kind, if that kind is cached.
    pub fn last_hit(&mut self, kind: RayKind) -> Option<&mut L> {
        self.last_hit.get_mut(kind.index())?.as_mut()
    }

    /// The shadow cache of sample `sample` of light `light`, if shadow rays are cached (all
    /// samples of a light share one unless `shadow_per_sample`).
    pub fn shadow(&mut self, light: u32, sample: u32) -> Option<&mut S> {
        if !self.config.shadow {
            return None;
        }
        let light = light as usize;
        let slot = if self.config.shadow_per_sample {
            sample as usize
        } else {
            0
        };
        if self.shadow.len() <= light {
            self.shadow.resize_with(light + 1, Vec::new);
        }
        let slots = &mut self.shadow[light];
        if slots.len() <= slot {
            slots.resize_with(slot + 1, || None);
        }
        Some(slots[slot].get_or_insert_with(&self.new_shadow))
    }

    /// Hits and misses per ray kind (indexed by [`RayKind::index`]; all lights together).
    pub fn stats(&self) -> [CacheStats; 4] {
        let mut stats = [CacheStats::default(); 4];
        for (k, cache) in self.last_hit.iter().enumerate() {
            if let Some(cache) = cache {
                stats[k] += cache.stats();
            }
        }
        for cache in self.shadow.iter().flatten().flatten() {
            stats[3] += cache.stats();
        }
        stats
    }
}
