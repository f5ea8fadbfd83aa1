//! `--config FILE.toml`: settings for any subcommand from a TOML file (SPEC §13).
//!
//! A table per subcommand path (`[data.build]`, `[eval]`, `[nav.trajectories]`) holds that
//! command's flags by name (`per_scene = 20` or `per-scene = 20`). The file only supplies flags:
//! they are added to the command line unless it already gives them, and clap then checks them
//! exactly as if typed, so a misspelt key is an error naming the flag. Each command's run record
//! holds the resolved settings, whichever way they came.

use clap::CommandFactory;
use sage_core::{Error, Result};
use std::path::Path;

/// The value of `--config` in a raw command line, if any.
pub fn config_path(argv: &[String]) -> Option<String> {
    argv.iter().enumerate().find_map(|(k, a)| {
        a.strip_prefix("--config=").map(str::to_string).or_else(|| {
            (a == "--config")
                .then(|| argv.get(k + 1).cloned())
                .flatten()
        })
    })
}

/// The subcommand path of a raw command line (`["data", "build"]`), found by walking the
/// command tree of `C` over the words that name subcommands.
pub fn subcommand_path<C: CommandFactory>(argv: &[String]) -> Vec<String> {
    let mut cmd = C::command();
    let mut path = Vec::new();
    let mut words = argv.iter().skip(1);
    while let Some(w) = words.next() {
        if w == "--threads" || w == "--config" {
            words.next();
            continue;
        }
        if w.starts_with('-') {
            continue;
        }
        match cmd.find_subcommand(w) {
            Some(sub) => {
                path.push(w.clone());
                cmd = sub.clone();
            }
            None => break,
        }
    }
    path
}

/// One TOML value as a flag value: strings as they are, numbers and booleans written out,
/// arrays joined by commas (the list flags' delimiter).
fn flag_value(v: &toml::Value) -> Option<String> {
    match v {
        toml::Value::String(s) => Some(s.clone()),
        toml::Value::Integer(i) => Some(i.to_string()),
        toml::Value::Float(f) => Some(f.to_string()),
        toml::Value::Boolean(b) => Some(b.to_string()),
        toml::Value::Array(items) => items
            .iter()
            .map(flag_value)
            .collect::<Option<Vec<_>>>()
            .map(|v| v.join(",")),
        _ => None,
    }
}

/// `argv` with the flags of `text`'s table for `path` added where the command line does not
/// give them. A boolean `true` adds the bare flag, `false` nothing.
///
/// # Errors
///
/// The text is not TOML (the error names the line), or a value is a table or date.
pub fn apply(text: &str, file: &Path, path: &[String], argv: &[String]) -> Result<Vec<String>> {
    let root: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| Error::format("TOML", e.to_string()).in_file(file))?;
    let mut table = Some(&root);
    for name in path {
        table = table
            .and_then(|t| t.get(name.as_str()))
            .and_then(toml::Value::as_table);
    }
    let mut out = argv.to_vec();
    let Some(table) = table else {
        return Ok(out);
    };
    let given = |flag: &str| {
        argv.iter()
            .any(|a| a == flag || a.starts_with(&format!("{flag}=")))
    };
    for (key, value) in table {
        if value.is_table() {
            continue;
        }
        let flag = format!("--{}", key.replace('_', "-"));
        if given(&flag) {
            continue;
        }
        let text = flag_value(value).ok_or_else(|| {
            Error::format(
                format!("[{}] {key}", path.join(".")),
                "expected a string, number, boolean or list",
            )
            .in_file(file)
        })?;
        match value {
            toml::Value::Boolean(true) => out.push(flag),
            toml::Value::Boolean(false) => {}
            _ => out.extend([flag, text]),
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn args(s: &str) -> Vec<String> {
        s.split_whitespace().map(str::to_string).collect()
    }

    #[test]
    fn a_table_supplies_the_flags_the_command_line_lacks() {
        let text = "[data.build]\nper_scene = 20\nseed = 3\nval = 0.2\n\n[eval]\nagent = \"oracle\"\n[demo]\nagents = [\"oracle\", \"random\"]\n";
        let argv = args("sage3d --config c.toml data build S --out D --seed 9");
        assert_eq!(config_path(&argv).as_deref(), Some("c.toml"));
        let path = subcommand_path::<crate::Cli>(&argv);
        assert_eq!(path, ["data", "build"]);
        let out = apply(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(
            out[argv.len()..],
            args("--per-scene 20 --val 0.2")[..],
            "the command line's --seed wins"
        );
        let demo = args("sage3d demo");
        let out = apply(text, Path::new("c.toml"), &["demo".into()], &demo).unwrap();
        assert_eq!(out[1..], args("demo --agents oracle,random")[..]);
        // No table for the command: nothing added.
        let nav = args("sage3d nav map S");
        let path = subcommand_path::<crate::Cli>(&nav);
        assert_eq!(apply(text, Path::new("c.toml"), &path, &nav).unwrap(), nav);
    }

    #[test]
    fn bad_files_name_the_file_and_line() {
        let e = apply(
            "[eval]\nagent = \n",
            Path::new("c.toml"),
            &["eval".into()],
            &[],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("c.toml") && e.contains("line 2"), "{e}");
        let e = apply(
            "[eval]\nwhen = 1979-05-27\n",
            Path::new("c.toml"),
            &["eval".into()],
            &[],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("[eval] when"), "{e}");
    }
}
