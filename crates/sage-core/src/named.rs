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

/// A list setting as its flag takes it: the values joined by commas (`1,2,1`), which is also
/// how a command's help shows the list's default.
pub fn comma_list<T: std::fmt::Display>(values: &[T]) -> String {
    values
        .iter()
        .map(ToString::to_string)
        .collect::<Vec<_>>()
        .join(",")
}

#[cfg(test)]
mod tests {
    use super::comma_list;

    #[test]
    fn a_list_reads_back_as_the_flag_splits_it() {
        let weights = [1.0f32, 2.5, 1.0];
        let text = comma_list(&weights);
        assert_eq!(text, "1,2.5,1");
        let back: Vec<f32> = text.split(',').map(|v| v.parse().unwrap()).collect();
        assert_eq!(back, weights);
        assert_eq!(comma_list::<u8>(&[]), "");
    }
}
