//! The JSON files of a scene folder: InteriorGS `labels.json` and `structure.json`, and our
//! `objects.json`. Each module parses text into the model (errors name the entry and field) and
//! turns the model back into a `serde_json::Value` for writing.

pub mod json;
pub mod labels;
pub mod objects_json;
pub mod structure;
