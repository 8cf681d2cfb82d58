//! What the name tables ([`BuilderKind`](crate::bvh::build::BuilderKind),
//! [`LayoutKind`](crate::bvh::layout::LayoutKind)) share: reading a name, writing it, and the
//! error of a name not in the table.

use std::fmt;

/// A name that is not in a name table: says what was named, the name given and every name
/// accepted, e.g. `unknown builder "sah"; expected one of insertion, binned-sah, ...`.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnknownName {
    /// What the name was for: `"builder"` or `"layout"`.
    pub what: &'static str,
    /// The name as given.
    pub name: String,
    /// Every name accepted, in the table's order.
    pub expected: Vec<&'static str>,
}

impl fmt::Display for UnknownName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "unknown {} {:?}; expected one of {}",
            self.what,
            self.name,
            self.expected.join(", ")
        )
    }
}

impl std::error::Error for UnknownName {}

/// The entry of `all` whose name is `name`, compared as the tables' names are written: case
/// ignored, `_` read as `-`, surrounding white space dropped (`"Binned_SAH"` is `binned-sah`).
pub(crate) fn parse_name<K: Copy>(
    what: &'static str,
    name: &str,
    all: &[K],
    name_of: impl Fn(K) -> &'static str,
) -> Result<K, UnknownName> {
    let canonical = name.trim().to_ascii_lowercase().replace('_', "-");
    all.iter()
        .copied()
        .find(|&k| name_of(k) == canonical)
        .ok_or_else(|| UnknownName {
            what,
            name: canonical,
            expected: all.iter().map(|&k| name_of(k)).collect(),
        })
}

/// `Display` (the entry's name, padded as asked) and `FromStr` (through [`parse_name`]) for a
/// name table: an enum with `const ALL: [Self; N]` and `const fn name(self) -> &'static str`;
/// `$what` says what its entries are (`"builder"`).
macro_rules! name_table {
    ($kind:ty, $what:literal) => {
        impl std::fmt::Display for $kind {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.pad(self.name())
            }
        }

        impl std::str::FromStr for $kind {
            type Err = $crate::bvh::UnknownName;

            /// An entry's name, case ignored and `_` read as `-`.
            fn from_str(name: &str) -> Result<Self, Self::Err> {
                $crate::bvh::name_table::parse_name($what, name, &<$kind>::ALL, <$kind>::name)
            }
        }
    };
}
pub(crate) use name_table;
