//! `--config FILE.toml`: settings for any subcommand from a TOML file (SPEC §13).
//!
//! A table per subcommand path (`[data.build]`, `[eval]`, `[nav.trajectories]`) holds that
//! command's flags by name (`per_scene = 20` or `per-scene = 20`); keys outside every table are
//! the global flags (`threads = 4`). The file only supplies flags: they are added to the command
//! line unless it already gives them, and clap then checks their values exactly as if typed.
//! The whole file is checked against the command tree first, so a misspelt table or key is an
//! error naming the file, the table and the key, whichever command runs; a value clap refuses is
//! named with the table and key it came from. Each command's run record holds the resolved
//! settings, whichever way they came.

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

/// Each flag a config file added (`--per-scene`) with where it came from (`[data.build]
/// per_scene in c.toml`), so that clap's refusal of its value can say so.
pub type Origins = Vec<(String, String)>;

/// A command line with a config file's flags added.
#[derive(Debug)]
pub struct Applied {
    /// The command line with the added flags after the typed ones.
    pub argv: Vec<String>,
    /// Where each added flag came from.
    pub origins: Origins,
}

/// Where the flag of a clap error's argument (`--yaw <YAW>`) came from, when a config file gave
/// it: `origins` as in [`Applied::origins`].
pub fn origin_of<'a>(origins: &'a [(String, String)], arg: &str) -> Option<&'a str> {
    let flag = arg.split([' ', '=']).next().unwrap_or(arg);
    origins
        .iter()
        .find(|(f, _)| f == flag)
        .map(|(_, origin)| origin.as_str())
}

/// `argv` with the flags of `text`'s table for `path` and its keys outside every table (the
/// global flags) added where the command line does not give them. A boolean `true` adds the
/// bare flag, `false` nothing.
///
/// # Errors
///
/// The text is not TOML (the error names the line); a table that names no command of `C`, or a
/// key that names no flag of its table's command (each named with the file, wherever it is in
/// the file); a value that is a table or date.
pub fn apply<C: CommandFactory>(
    text: &str,
    file: &Path,
    path: &[String],
    argv: &[String],
) -> Result<Applied> {
    let root: toml::Table = text
        .parse()
        .map_err(|e: toml::de::Error| Error::format("TOML", e.to_string()).in_file(file))?;
    let cmd = C::command();
    let globals: Vec<String> = cmd
        .get_arguments()
        .filter(|a| a.is_global_set() && a.get_id() != "config")
        .filter_map(|a| a.get_long().map(str::to_string))
        .collect();
    check_table(&root, &cmd, &globals, &[]).map_err(|e| e.in_file(file))?;
    let mut table = Some(&root);
    for name in path {
        table = table
            .and_then(|t| t.get(name.as_str()))
            .and_then(toml::Value::as_table);
    }
    let mut applied = Applied {
        argv: argv.to_vec(),
        origins: Vec::new(),
    };
    let leaf = path
        .iter()
        .try_fold(cmd.clone(), |c, name| c.find_subcommand(name).cloned());
    let typed: Vec<&str> = argv
        .iter()
        .filter_map(|a| a.strip_prefix("--"))
        .map(|a| a.split('=').next().unwrap_or(a))
        .collect();
    // A flag the command line gives, or one it gives that cannot go with this flag (the
    // typed `--scale-points` overrides a file's `scale`, as the typed flag wins anywhere).
    let given = |flag: &str| {
        let name = flag.trim_start_matches('-');
        typed.contains(&name)
            || leaf
                .as_ref()
                .is_some_and(|leaf| typed.iter().any(|t| conflict(leaf, name, t)))
    };
    let mut add = |table: &toml::Table, name: &str| -> Result<()> {
        for (key, value) in table {
            if value.is_table() {
                continue;
            }
            let flag = format!("--{}", key.replace('_', "-"));
            if given(&flag) || applied.origins.iter().any(|(f, _)| *f == flag) {
                continue;
            }
            let origin = format!("{name}{key}");
            let text = flag_value(value).ok_or_else(|| {
                Error::format(&origin, "expected a string, number, boolean or list").in_file(file)
            })?;
            match value {
                toml::Value::Boolean(true) => applied.argv.push(flag.clone()),
                toml::Value::Boolean(false) => {}
                _ => applied.argv.extend([flag.clone(), text]),
            }
            applied
                .origins
                .push((flag, format!("{origin} in {}", file.display())));
        }
        Ok(())
    };
    if let Some(table) = table.filter(|_| !path.is_empty()) {
        add(table, &format!("[{}] ", path.join(".")))?;
    }
    add(&root, "")?;
    Ok(applied)
}

/// Whether flags `a` and `b` of `cmd` (long names) cannot be given together, declared on
/// either. Global flags conflict with none.
fn conflict(cmd: &clap::Command, a: &str, b: &str) -> bool {
    let arg = |name: &str| {
        cmd.get_arguments()
            .find(|x| x.get_long() == Some(name) && !x.is_global_set())
    };
    let (Some(a), Some(b)) = (arg(a), arg(b)) else {
        return false;
    };
    let ids = |x: &clap::Arg| {
        cmd.get_arg_conflicts_with(x)
            .into_iter()
            .map(|c| c.get_id().clone())
            .collect::<Vec<_>>()
    };
    ids(a).contains(b.get_id()) || ids(b).contains(a.get_id())
}

/// Checks `table`, the table of the command `cmd` at `at` (empty: the file's top level): each
/// table inside names a subcommand of `cmd`, each other key a long flag of `cmd` (at the top
/// level, a global flag).
fn check_table(
    table: &toml::Table,
    cmd: &clap::Command,
    globals: &[String],
    at: &[String],
) -> Result<()> {
    let command = std::iter::once("sage3d")
        .chain(at.iter().map(String::as_str))
        .collect::<Vec<_>>()
        .join(" ");
    for (key, value) in table {
        if let Some(inner) = value.as_table() {
            let inner_at = [at, std::slice::from_ref(key)].concat();
            let Some(sub) = cmd.find_subcommand(key) else {
                let known: Vec<&str> = cmd.get_subcommands().map(|c| c.get_name()).collect();
                let what = if known.is_empty() {
                    format!("not a command (`{command}` has no subcommands)")
                } else {
                    format!("not a command (`{command}` has {})", known.join(", "))
                };
                return Err(Error::format(format!("[{}]", inner_at.join(".")), what));
            };
            check_table(inner, sub, globals, &inner_at)?;
            continue;
        }
        let flag = key.replace('_', "-");
        let own = !at.is_empty()
            && cmd.get_arguments().any(|a| {
                a.get_long() == Some(flag.as_str())
                    || a.get_all_aliases()
                        .is_some_and(|v| v.contains(&flag.as_str()))
            });
        if own || globals.contains(&flag) {
            continue;
        }
        return Err(if at.is_empty() {
            Error::format(
                key.clone(),
                format!(
                    "not a global flag (the keys outside every table: {}; a command's flags go \
                     in its table, such as [data.build])",
                    globals.join(", ")
                ),
            )
        } else {
            Error::format(
                format!("[{}] {key}", at.join(".")),
                format!("`{command}` has no flag --{flag}"),
            )
        });
    }
    Ok(())
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
        let out = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv)
            .unwrap()
            .argv;
        assert_eq!(
            out[argv.len()..],
            args("--per-scene 20 --val 0.2")[..],
            "the command line's --seed wins"
        );
        let demo = args("sage3d demo");
        let out = apply::<crate::Cli>(text, Path::new("c.toml"), &["demo".into()], &demo)
            .unwrap()
            .argv;
        assert_eq!(out[1..], args("demo --agents oracle,random")[..]);
        // No table for the command: nothing added.
        let nav = args("sage3d nav map S");
        let path = subcommand_path::<crate::Cli>(&nav);
        assert_eq!(
            apply::<crate::Cli>(text, Path::new("c.toml"), &path, &nav)
                .unwrap()
                .argv,
            nav
        );
    }

    #[test]
    fn a_typed_flag_overrides_the_file_flags_it_cannot_go_with() {
        let text = "[scene.import]\nscale = 0.5\n[render]\nyaw = 30\nwidth = 320\n";
        let argv =
            args("sage3d scene import C --out S --scale-points 0,0,0:1,0,0 --scale-distance 2");
        let path = subcommand_path::<crate::Cli>(&argv);
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(
            applied.argv, argv,
            "the file's scale goes with neither typed flag"
        );
        let argv = args("sage3d scene import C --out S --scale-distance 2");
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(
            applied.argv, argv,
            "the typed --scale-distance, alone, still wins"
        );
        let argv = args("sage3d render S --out R --camera cam.json");
        let path = subcommand_path::<crate::Cli>(&argv);
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(
            applied.argv, argv,
            "a camera file sets the pose and size itself"
        );
        let argv = args("sage3d render S --out R");
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(applied.argv[argv.len()..], args("--width 320 --yaw 30")[..]);
    }

    #[test]
    fn bad_files_name_the_file_and_line() {
        let e = apply::<crate::Cli>(
            "[eval]\nagent = \n",
            Path::new("c.toml"),
            &["eval".into()],
            &[],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("c.toml") && e.contains("line 2"), "{e}");
        let e = apply::<crate::Cli>(
            "[eval]\nwhen = 1979-05-27\n",
            Path::new("c.toml"),
            &["eval".into()],
            &[],
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("[eval] when"), "{e}");
    }

    #[test]
    fn global_keys_apply_to_every_command_and_say_where_they_came_from() {
        let text = "threads = 2\n[render]\nyaw = 30\n";
        let argv = args("sage3d render S --out R");
        let path = subcommand_path::<crate::Cli>(&argv);
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(applied.argv[argv.len()..], args("--yaw 30 --threads 2")[..]);
        assert_eq!(
            origin_of(&applied.origins, "--yaw <YAW>"),
            Some("[render] yaw in c.toml")
        );
        assert_eq!(origin_of(&applied.origins, "--out <OUT>"), None);
    }

    #[test]
    fn misspelt_tables_and_keys_are_errors_naming_them_whatever_command_runs() {
        let argv = args("sage3d demo");
        let check = |text: &str| {
            apply::<crate::Cli>(text, Path::new("c.toml"), &["demo".into()], &argv)
                .map(|_| ())
                .map_err(|e| e.to_string())
        };
        assert_eq!(
            check("[data.build]\nper_scene = 2\n[eval]\nagent = \"oracle\"\n"),
            Ok(())
        );
        for (text, says) in [
            (
                "[rendr]\nyaw = 3\n",
                "[rendr]: not a command (`sage3d` has ",
            ),
            (
                "[data.biuld]\nseed = 3\n",
                "[data.biuld]: not a command (`sage3d data` has ",
            ),
            (
                "[render]\nbogus = 1\n",
                "[render] bogus: `sage3d render` has no flag --bogus",
            ),
            (
                "[data.build]\nper_sene = 1\n",
                "`sage3d data build` has no flag --per-sene",
            ),
            ("per_scene = 20\n", "per_scene: not a global flag"),
            ("config = \"other.toml\"\n", "config: not a global flag"),
        ] {
            let e = check(text).unwrap_err();
            assert!(e.contains("c.toml") && e.contains(says), "{text:?}: {e}");
        }
    }
}
