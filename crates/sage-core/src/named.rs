//! Settings named by a word (`"gpu"`, `"navila_small"`): one macro gives such a type the
//! conversions that let serde read and write it exactly as its command-line flag parses and
//! prints it, so a settings file, Python and the flag accept the same names and refuse the
//! others with the same message.

/// Implements `TryFrom<String>` (by the type's `FromStr`) and `From<T> for String` (by its
/// `Display`), for `#[serde(try_from = "String", into = "String")]`.
#[macro_export]
macro_rules! named_by_string {
    ($ty:ty) => {
        impl ::std::convert::TryFrom<::std::string::String> for $ty {
            type Error = <$ty as ::std::str::FromStr>::Err;

            fn try_from(name: ::std::string::String) -> ::std::result::Result<$ty, Self::Error> {
                name.parse()
            }
        }

        impl ::std::convert::From<$ty> for ::std::string::String {
            fn from(value: $ty) -> ::std::string::String {
                value.to_string()
            }
        }
    };
}
