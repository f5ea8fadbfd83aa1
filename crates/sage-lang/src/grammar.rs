//! A tiny template grammar: `[a|b|c]` picks one alternative (an empty one makes the part
//! optional), `{slot}` inserts a value. The result is tidied into a sentence: single spaces, no
//! space before punctuation, a capital first letter and a final full stop.

use rand::Rng;
use std::collections::BTreeMap;

/// Expands `template` with `slots` into a tidy sentence; `None` when it uses a slot that is not
/// given or is malformed (an unclosed bracket or brace).
pub fn expand(
    template: &str,
    slots: &BTreeMap<&str, String>,
    rng: &mut impl Rng,
) -> Option<String> {
    Some(tidy(&fill(template, slots, rng)?))
}

/// Expands `template` without tidying (for phrases spliced into other templates). Brackets nest.
pub fn fill(template: &str, slots: &BTreeMap<&str, String>, rng: &mut impl Rng) -> Option<String> {
    let mut out = String::new();
    let mut rest = template;
    while let Some(c) = rest.chars().next() {
        match c {
            '[' => {
                let (options, after) = split_choice(rest)?;
                let pick = options[rng.random_range(0..options.len())];
                out.push_str(&fill(pick, slots, rng)?);
                rest = after;
            }
            '{' => {
                let end = rest.find('}')?;
                out.push_str(slots.get(&rest[1..end])?);
                rest = &rest[end + 1..];
            }
            ']' | '}' => return None,
            _ => {
                out.push(c);
                rest = &rest[c.len_utf8()..];
            }
        }
    }
    Some(out)
}

/// The top-level alternatives of the choice `s` starts with, and the text after it.
fn split_choice(s: &str) -> Option<(Vec<&str>, &str)> {
    let mut depth = 0usize;
    let mut start = 1;
    let mut options = Vec::new();
    for (i, c) in s.char_indices() {
        match c {
            '[' => depth += 1,
            ']' => {
                depth -= 1;
                if depth == 0 {
                    options.push(&s[start..i]);
                    return Some((options, &s[i + 1..]));
                }
            }
            '|' if depth == 1 => {
                options.push(&s[start..i]);
                start = i + 1;
            }
            _ => {}
        }
    }
    None
}

/// Single spaces, no space before `,` `.` `;` `?` `!`, first letter upper case, ending with
/// punctuation.
pub fn tidy(s: &str) -> String {
    let mut t = s.split_whitespace().collect::<Vec<_>>().join(" ");
    for p in [",", ".", ";", "?", "!"] {
        t = t.replace(&format!(" {p}"), p);
    }
    let mut chars = t.chars();
    let mut out: String = match chars.next() {
        Some(f) => f.to_uppercase().chain(chars).collect(),
        None => return t,
    };
    if !out.ends_with(['.', '?', '!']) {
        out.push('.');
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::SeedableRng;

    #[test]
    fn choices_slots_and_tidying() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let slots: BTreeMap<&str, String> = [("goal", "the sofa".to_string())].into();
        for _ in 0..20 {
            let s = expand("[please |]go to {goal} [now|]", &slots, &mut rng).unwrap();
            let all = [
                "Please go to the sofa now.",
                "Please go to the sofa.",
                "Go to the sofa now.",
                "Go to the sofa.",
            ];
            assert!(all.contains(&s.as_str()), "{s}");
        }
        assert_eq!(expand("go to {missing}", &slots, &mut rng), None);
        assert_eq!(expand("go [to", &slots, &mut rng), None);
        assert_eq!(tidy("  walk   to the sofa "), "Walk to the sofa.");
        let nested = expand("[[a|b] c|d]", &slots, &mut rng).unwrap();
        assert!(
            ["A c.", "B c.", "D."].contains(&nested.as_str()),
            "{nested}"
        );
        assert_eq!(expand("a ] b", &slots, &mut rng), None);
    }
}
