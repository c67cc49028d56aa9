//! `enum_with_unknown!`: open enums for protocol code points.
//!
//! A new mailbox type, AL status code or abort code is data, not a parse failure: every such
//! enum has an `Unknown(raw)` catch-all and converts losslessly to and from its raw integer.

/// Declares an open enum over an integer type with `From` conversions both ways.
///
/// ```ignore
/// enum_with_unknown! {
///     /// Doc.
///     pub enum Kind(u8) {
///         /// Doc.
///         A = 1,
///     }
/// }
/// ```
macro_rules! enum_with_unknown {
    (
        $( #[$enum_attr:meta] )*
        pub enum $name:ident($ty:ty) {
            $(
              $( #[$variant_attr:meta] )*
              $variant:ident = $value:expr
            ),+ $(,)?
        }
    ) => {
        $( #[$enum_attr] )*
        #[derive(Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Clone, Copy)]
        pub enum $name {
            $(
              $( #[$variant_attr] )*
              $variant
            ),*,
            /// A value this version does not name; kept so that it round-trips.
            Unknown($ty)
        }

        impl ::core::convert::From<$ty> for $name {
            fn from(value: $ty) -> Self {
                match value {
                    $( value if value == $value => $name::$variant ),*,
                    other => $name::Unknown(other)
                }
            }
        }

        impl ::core::convert::From<$name> for $ty {
            fn from(value: $name) -> Self {
                match value {
                    $( $name::$variant => $value ),*,
                    $name::Unknown(other) => other
                }
            }
        }
    }
}

pub(crate) use enum_with_unknown;
