//! The library's name tables ([`BuilderKind`], [`LayoutKind`], [`BuildQuality`]) as clap values: the names clap
//! offers, checks and lists in `--help` are the library's, with each one's summary.

use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser};
use hbv::bvh::build::{BuildQuality, BuilderKind};
use hbv::bvh::layout::LayoutKind;

/// `--builder NAME`: one of [`BuilderKind::ALL`].
pub fn builder_kind() -> impl TypedValueParser<Value = BuilderKind> {
    names(&BuilderKind::ALL, BuilderKind::name, BuilderKind::summary)
}

/// `--quality NAME`: one of [`BuildQuality::ALL`].
pub fn build_quality() -> impl TypedValueParser<Value = BuildQuality> {
    names(
        &BuildQuality::ALL,
        BuildQuality::name,
        BuildQuality::summary,
    )
}

/// `--layout NAME`: one of [`LayoutKind::ALL`].
pub fn layout_kind() -> impl TypedValueParser<Value = LayoutKind> {
    names(&LayoutKind::ALL, LayoutKind::name, LayoutKind::summary)
}

/// A parser that takes exactly the names of `all` (clap refuses any other, listing them) and
/// gives the entry named.
fn names<K: Copy + Send + Sync + 'static>(
    all: &'static [K],
    name: fn(K) -> &'static str,
    summary: fn(K) -> &'static str,
) -> impl TypedValueParser<Value = K> {
    let values = all
        .iter()
        .map(move |&k| PossibleValue::new(name(k)).help(summary(k)));
    PossibleValuesParser::new(values).map(move |given: String| {
        *all.iter()
            .find(|&&k| name(k) == given)
            .expect("clap accepts only the names of the table")
    })
}
