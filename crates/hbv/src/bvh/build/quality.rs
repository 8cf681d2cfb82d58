//! Build quality settings, named as Embree's (`RTC_BUILD_QUALITY_LOW`, `_MEDIUM`, `_HIGH`): the
//! one table from a quality to the builder, optimizer and leaf size that make it, used by the
//! command line (`--quality`) and the Python module (`quality=`).

use super::{BuilderKind, BuilderOptions};
use crate::bvh::name_table::name_table;
use crate::bvh::BuildTree;
use crate::mesh::TriangleMesh;

/// How much time a build may spend to make the tree faster to trace: a builder, an optimizer
/// and a leaf size chosen together (BENCHMARKS.md, "Tree quality per builder" and "Builds
/// against Embree", measure each).
///
/// | quality | builder | optimizer | leaf size | for |
/// | --- | --- | --- | --- | --- |
/// | `low` | LBVH | none | ≤ 4 | rebuilding often: about a third of binned SAH's build time, rays 10–15 % slower |
/// | `medium` (default) | binned SAH | none | ≤ 8, SAH-terminated | a build followed by many rays |
/// | `high` | binned SAH | reinsertion (Bittner et al. 2013) | ≤ 8, SAH-terminated | a tree built once and traced for long, or saved |
///
/// ```
/// use hbv::bvh::build::{BuildQuality, BuilderKind};
/// let quality: BuildQuality = "high".parse().unwrap();
/// assert_eq!(quality.builder(), BuilderKind::BinnedSah);
/// assert!(quality.builder_options().optimize);
/// assert_eq!(BuildQuality::default(), BuildQuality::Medium);
/// ```
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum BuildQuality {
    /// The fastest build: a Morton-code LBVH ([`LbvhBuilder`](super::LbvhBuilder)).
    Low,
    /// Binned SAH ([`BinnedSahBuilder`](super::BinnedSahBuilder)): the best time to a first
    /// batch of rays, and the default.
    #[default]
    Medium,
    /// Binned SAH improved by reinsertion
    /// ([`ReinsertionOptimizer`](crate::bvh::optimize::ReinsertionOptimizer)).
    High,
}

impl BuildQuality {
    /// Every quality, from the fastest build to the fastest tree.
    pub const ALL: [BuildQuality; 3] =
        [BuildQuality::Low, BuildQuality::Medium, BuildQuality::High];

    /// The name used on the command line and in Python.
    pub const fn name(self) -> &'static str {
        match self {
            BuildQuality::Low => "low",
            BuildQuality::Medium => "medium",
            BuildQuality::High => "high",
        }
    }

    /// One line saying what the quality builds, for help texts.
    pub const fn summary(self) -> &'static str {
        match self {
            BuildQuality::Low => "LBVH, leaves of at most 4: the fastest build (for rebuilds)",
            BuildQuality::Medium => "Binned SAH, leaves of at most 8 (the default)",
            BuildQuality::High => "Binned SAH + reinsertion optimization: the fastest rays",
        }
    }

    /// The builder this quality uses.
    pub const fn builder(self) -> BuilderKind {
        match self {
            BuildQuality::Low => BuilderKind::Lbvh,
            BuildQuality::Medium | BuildQuality::High => BuilderKind::BinnedSah,
        }
    }

    /// The options [`BuildQuality::builder`] is given: its own leaf size, and reinsertion
    /// optimization for `high`.
    pub fn builder_options(self) -> BuilderOptions {
        BuilderOptions {
            optimize: self == BuildQuality::High,
            ..BuilderOptions::default()
        }
    }

    /// Builds the tree over `mesh` at this quality.
    pub fn build(self, mesh: &TriangleMesh) -> BuildTree {
        self.builder().build(mesh, &self.builder_options())
    }
}

name_table!(BuildQuality, "quality");

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bvh::build::primitive_bounds;
    use crate::bvh::expected_tests;
    use crate::mesh::procedural::default_scene;

    #[test]
    fn names_round_trip_and_unknown_names_list_every_quality() {
        for quality in BuildQuality::ALL {
            assert_eq!(quality.to_string().parse::<BuildQuality>(), Ok(quality));
        }
        assert_eq!(" HIGH ".parse::<BuildQuality>(), Ok(BuildQuality::High));
        assert_eq!(
            "best".parse::<BuildQuality>().unwrap_err().to_string(),
            "unknown quality \"best\"; expected one of low, medium, high"
        );
    }

    #[test]
    fn the_default_is_todays_default_build() {
        let medium = BuildQuality::default();
        assert_eq!(medium.builder(), BuilderKind::BinnedSah);
        assert_eq!(medium.builder_options(), BuilderOptions::default());
    }

    #[test]
    fn higher_qualities_make_cheaper_trees() {
        let mesh = default_scene(1);
        let bounds = primitive_bounds(&mesh);
        let cost: Vec<f64> = BuildQuality::ALL
            .iter()
            .map(|quality| {
                let tree = quality.build(&mesh);
                tree.validate(&bounds, 8).unwrap();
                expected_tests(&tree)
            })
            .collect();
        assert!(
            cost[0] > cost[1] && cost[1] > cost[2],
            "E[X] low, medium, high: {cost:?}"
        );
    }
}
