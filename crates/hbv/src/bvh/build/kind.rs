//! The builders by name: the one table from a name (`binned-sah`) to a [`Builder`], used by the
//! command line, the Python module and the examples.

use super::{
    BinnedSahBuilder, BinnedSahConfig, Builder, InsertionBuilder, InsertionConfig, InsertionOrder,
    LbvhBuilder, LbvhConfig, MedianBuilder, MedianConfig, PlocBuilder, PlocConfig, SweepSahBuilder,
    SweepSahConfig,
};
use crate::bvh::name_table::name_table;
use crate::bvh::optimize::ReinsertionOptimizer;
use crate::bvh::BuildTree;
use crate::mesh::TriangleMesh;

/// A tree construction algorithm, by name.
///
/// ```
/// use hbv::bvh::build::{BuilderKind, BuilderOptions};
/// let kind: BuilderKind = "binned-sah".parse().unwrap();
/// assert_eq!(kind, BuilderKind::BinnedSah);
/// assert_eq!(kind.to_string(), "binned-sah");
/// assert_eq!(kind.builder(&BuilderOptions::default()).name(), "binned-sah");
/// ```
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BuilderKind {
    /// Goldsmith–Salmon incremental insertion ([`InsertionBuilder`]).
    Insertion,
    /// Top-down SAH over binned centroids ([`BinnedSahBuilder`]).
    BinnedSah,
    /// Top-down SAH over every split position ([`SweepSahBuilder`]).
    SweepSah,
    /// Top-down object-median split ([`MedianBuilder`]).
    Median,
    /// Morton-code LBVH ([`LbvhBuilder`]).
    Lbvh,
    /// Parallel locally-ordered clustering ([`PlocBuilder`]).
    Ploc,
}

/// What a builder is asked for beyond its name: every field's default is the builder's own.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BuilderOptions {
    /// Most triangles per leaf; `None` for the builder's default (1 for insertion, the
    /// seed's model).
    pub leaf_size: Option<usize>,
    /// The order in which the insertion builder inserts triangles (the others ignore it).
    pub insertion_order: InsertionOrder,
    /// Whether [`BuilderKind::build`] improves the tree by reinsertion (Bittner et al. 2013)
    /// after building it.
    pub optimize: bool,
}

impl BuilderOptions {
    /// The insertion builder these options describe: for callers that want its report
    /// ([`InsertionBuilder::build_with_report`]) as well as the tree.
    pub fn insertion_builder(&self) -> InsertionBuilder {
        InsertionBuilder::new(InsertionConfig {
            order: self.insertion_order,
            max_leaf_size: self
                .leaf_size
                .unwrap_or(BuilderKind::Insertion.default_leaf_size()),
        })
    }
}

impl BuilderKind {
    /// Every builder, in the order tables list them.
    pub const ALL: [BuilderKind; 6] = [
        BuilderKind::Insertion,
        BuilderKind::BinnedSah,
        BuilderKind::SweepSah,
        BuilderKind::Median,
        BuilderKind::Lbvh,
        BuilderKind::Ploc,
    ];

    /// The name used on the command line, in Python and in tables; [`Builder::name`] of the
    /// builder it makes.
    pub const fn name(self) -> &'static str {
        match self {
            BuilderKind::Insertion => "insertion",
            BuilderKind::BinnedSah => "binned-sah",
            BuilderKind::SweepSah => "sweep-sah",
            BuilderKind::Median => "median",
            BuilderKind::Lbvh => "lbvh",
            BuilderKind::Ploc => "ploc",
        }
    }

    /// One line saying what the builder does, for help texts.
    pub const fn summary(self) -> &'static str {
        match self {
            BuilderKind::Insertion => {
                "Goldsmith–Salmon incremental insertion (the seed's construction)"
            }
            BuilderKind::BinnedSah => "Top-down SAH over binned centroids (Wald 2007), parallel",
            BuilderKind::SweepSah => "Top-down SAH over every split position (full sweep)",
            BuilderKind::Median => "Top-down object-median split (the simple baseline)",
            BuilderKind::Lbvh => "Morton-code LBVH (the fast baseline)",
            BuilderKind::Ploc => {
                "Parallel locally-ordered clustering (Meister & Bittner 2018), parallel"
            }
        }
    }

    /// The leaf size this builder uses when `options` names none.
    pub fn default_leaf_size(self) -> usize {
        match self {
            BuilderKind::Insertion => InsertionConfig::default().max_leaf_size,
            BuilderKind::BinnedSah => BinnedSahConfig::default().leaf.max_leaf_size,
            BuilderKind::SweepSah => SweepSahConfig::default().leaf.max_leaf_size,
            BuilderKind::Median => MedianConfig::default().max_leaf_size,
            BuilderKind::Lbvh => LbvhConfig::default().max_leaf_size,
            BuilderKind::Ploc => PlocConfig::default().leaf.max_leaf_size,
        }
    }

    /// The builder this name stands for, configured by `options` (its defaults elsewhere).
    pub fn builder(self, options: &BuilderOptions) -> Box<dyn Builder> {
        let leaf = options.leaf_size.unwrap_or(self.default_leaf_size());
        match self {
            BuilderKind::Insertion => Box::new(options.insertion_builder()),
            BuilderKind::BinnedSah => {
                let mut config = BinnedSahConfig::default();
                config.leaf.max_leaf_size = leaf;
                Box::new(BinnedSahBuilder::new(config))
            }
            BuilderKind::SweepSah => {
                let mut config = SweepSahConfig::default();
                config.leaf.max_leaf_size = leaf;
                Box::new(SweepSahBuilder::new(config))
            }
            BuilderKind::Median => Box::new(MedianBuilder::new(MedianConfig {
                max_leaf_size: leaf,
            })),
            BuilderKind::Lbvh => Box::new(LbvhBuilder::new(LbvhConfig {
                max_leaf_size: leaf,
            })),
            BuilderKind::Ploc => {
                let mut config = PlocConfig::default();
                config.leaf.max_leaf_size = leaf;
                Box::new(PlocBuilder::new(config))
            }
        }
    }

    /// Builds the tree over `mesh`, and improves it by reinsertion when `options.optimize`.
    pub fn build(self, mesh: &TriangleMesh, options: &BuilderOptions) -> BuildTree {
        let mut tree = self.builder(options).build(mesh);
        if options.optimize {
            ReinsertionOptimizer::default().optimize(&mut tree);
        }
        tree
    }
}

name_table!(BuilderKind, "builder");

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_round_trip_and_name_the_builders_they_make() {
        for kind in BuilderKind::ALL {
            assert_eq!(kind.to_string().parse::<BuilderKind>(), Ok(kind));
            assert_eq!(kind.builder(&BuilderOptions::default()).name(), kind.name());
        }
        assert_eq!(
            " Binned_SAH ".parse::<BuilderKind>(),
            Ok(BuilderKind::BinnedSah)
        );
    }

    #[test]
    fn an_unknown_name_lists_every_builder() {
        let error = "sah".parse::<BuilderKind>().unwrap_err();
        assert_eq!(
            error.to_string(),
            "unknown builder \"sah\"; expected one of insertion, binned-sah, sweep-sah, median, lbvh, ploc"
        );
    }

    #[test]
    fn leaf_size_defaults_are_the_builders_own() {
        assert_eq!(BuilderKind::Insertion.default_leaf_size(), 1);
        for kind in BuilderKind::ALL {
            assert!(kind.default_leaf_size() >= 1);
        }
    }
}
