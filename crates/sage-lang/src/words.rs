//! Words: how categories, rooms and areas are said, and the lexicons the grammar and the
//! validator share (object nouns, relation phrases, carrying verbs, needs, attribute words).

/// The noun phrase of a category: `coffee_table` → `coffee table`, `tv_stand` → `TV stand`.
pub fn noun(category: &str) -> String {
    category
        .split('_')
        .filter(|w| !w.is_empty())
        .map(|w| match w {
            "tv" => "TV".to_string(),
            _ => w.to_string(),
        })
        .collect::<Vec<_>>()
        .join(" ")
}

/// How a room type is said: `Living Room` → `living room`, `master_bedroom` → `master bedroom`.
pub fn room_name(room_type: &str) -> String {
    let n = noun(&sage_scene::object::normalize_category(room_type));
    if n == "unknown" { "room".into() } else { n }
}

/// Lower-case words of a text (letters, digits, `'` and `_` kept inside words).
pub fn tokens(text: &str) -> Vec<String> {
    text.split(|c: char| !(c.is_alphanumeric() || c == '\'' || c == '_' || c == '-'))
        .map(|w| w.trim_matches(|c| c == '\'' || c == '-').to_lowercase())
        .filter(|w| !w.is_empty())
        .collect()
}

/// True when `words` holds `phrase` (space-separated words) as consecutive words.
pub fn contains_phrase(words: &[String], phrase: &str) -> bool {
    let p: Vec<&str> = phrase.split(' ').collect();
    !p.is_empty()
        && words
            .windows(p.len())
            .any(|w| w.iter().zip(&p).all(|(a, b)| a == b))
}

/// Object nouns the validator looks for: a noun of this list in an instruction must name
/// something of the scene's text map (singular forms; plurals with `s` are matched too).
pub const OBJECT_NOUNS: &[&str] = &[
    "armchair",
    "bathtub",
    "bed",
    "bench",
    "bin",
    "book",
    "bookcase",
    "bookshelf",
    "box",
    "cabinet",
    "chair",
    "clock",
    "closet",
    "computer",
    "couch",
    "counter",
    "cup",
    "curtain",
    "desk",
    "dishwasher",
    "dispenser",
    "door",
    "dresser",
    "fireplace",
    "fridge",
    "lamp",
    "laptop",
    "mannequin",
    "microwave",
    "mirror",
    "monitor",
    "nightstand",
    "oven",
    "painting",
    "piano",
    "picture",
    "plant",
    "printer",
    "rack",
    "refrigerator",
    "register",
    "rug",
    "shelf",
    "shower",
    "sink",
    "sofa",
    "stool",
    "stove",
    "table",
    "television",
    "toilet",
    "tv",
    "vase",
    "wardrobe",
    "washer",
    "whiteboard",
    "window",
];

/// Words that name the same kind of thing (each group is interchangeable for grounding).
pub const SYNONYMS: &[&[&str]] = &[
    &["fridge", "refrigerator"],
    &["sofa", "couch"],
    &["tv", "television"],
    &["bookshelf", "bookcase", "shelf", "shelving"],
    &["wardrobe", "closet"],
    &["painting", "picture"],
    &["bin", "trash"],
    &["box", "crate"],
    &["register", "till"],
];

/// Relation phrases (the defining feature of Relative_Relationship).
pub const RELATION_PHRASES: &[&str] = &[
    "next to",
    "beside",
    "across from",
    "opposite",
    "left of",
    "right of",
    "on the left",
    "on the right",
    "behind",
    "in front of",
    "near",
    "on top of",
    "closest to",
    "by the",
    "between",
];

/// Words that make a destination an area (the defining feature of Area-based).
pub const AREA_WORDS: &[&str] = &["area", "zone", "corner", "space", "section", "spot"];

/// Carrying verbs (the defining feature of Add_Object).
pub const CARRY_VERBS: &[&str] = &[
    "bring", "take", "carry", "move", "put", "deliver", "fetch", "return", "drop", "place", "grab",
    "pick up", "hand",
];

/// First-person words that mark a human need (the defining feature of Scenario_Driven).
pub const NEED_WORDS: &[&str] = &[
    "i", "i'm", "i've", "i'd", "i'll", "me", "my", "we", "we're", "our", "us", "let's",
];

/// Motion verbs (the defining feature of Single-Goal).
pub const MOTION_VERBS: &[&str] = &[
    "go", "walk", "head", "move", "navigate", "proceed", "make", "leave", "find", "get", "return",
    "travel", "come",
];

/// Step and angle words (the defining feature of Base-Action).
pub const BASE_ACTION_WORDS: &[&str] = &["step", "steps", "degree", "degrees", "turn", "rotate"];

/// Attribute words beyond the colour words of `sage_scene::vocabulary::COLORS` (states,
/// contents, sizes, materials).
pub const ATTRIBUTE_WORDS: &[&str] = &[
    "open",
    "closed",
    "half-open",
    "lit",
    "switched-on",
    "switched-off",
    "empty",
    "full",
    "small",
    "large",
    "big",
    "medium-sized",
    "tall",
    "wooden",
    "metal",
    "glass",
    "leather",
    "fabric",
    "marble",
    "plastic",
    "ceramic",
    "velvet",
    "striped",
    "patterned",
];

/// Number words for counts 1–12.
pub fn number_word(n: usize) -> String {
    const W: [&str; 13] = [
        "zero", "one", "two", "three", "four", "five", "six", "seven", "eight", "nine", "ten",
        "eleven", "twelve",
    ];
    W.get(n).map_or_else(|| n.to_string(), |w| w.to_string())
}

/// The adjective of a material word (`wood` → `wooden`).
pub fn material_adjective(m: &str) -> String {
    match m {
        "wood" => "wooden".into(),
        other => other.replace('_', " "),
    }
}

/// The adjective of a state for a category (`on` → `lit` for lamps, `switched-on` otherwise).
pub fn state_adjective(state: &str, category: &str) -> String {
    match state {
        "on" if category.contains("lamp") || category.contains("light") => "lit".into(),
        "on" => "switched-on".into(),
        "off" => "switched-off".into(),
        other => other.replace('_', "-"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nouns_and_rooms_read_naturally() {
        assert_eq!(noun("coffee_table"), "coffee table");
        assert_eq!(noun("tv_stand"), "TV stand");
        assert_eq!(room_name("Living Room"), "living room");
        assert_eq!(room_name(""), "room");
    }

    #[test]
    fn tokens_and_phrases() {
        let t = tokens("I'm thirsty, bring me a drink from the fridge next-to chair_3.");
        assert!(t.contains(&"i'm".to_string()) && t.contains(&"chair_3".to_string()));
        assert!(contains_phrase(
            &tokens("walk across from the sofa"),
            "across from"
        ));
        assert!(!contains_phrase(
            &tokens("walk across the room from"),
            "across from"
        ));
    }
}
