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
use std::collections::BTreeMap;
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

/// Whether a raw command line asks for help or the version: `-h`, `--help`, `-V` or
/// `--version` before a typed `--`, or `help` straight after its subcommands where another
/// subcommand could stand (`sage3d help`, `sage3d data help build`; global flags may stand
/// between; not `sage3d scene info help`, a path).
pub fn asks_for_help<C: CommandFactory>(argv: &[String]) -> bool {
    let flags_end = argv.iter().position(|a| a == "--").unwrap_or(argv.len());
    let words = argv.get(1..flags_end).unwrap_or_default();
    if words
        .iter()
        .any(|a| matches!(a.as_str(), "-h" | "--help" | "-V" | "--version"))
    {
        return true;
    }
    let mut cmd = C::command();
    let mut words = words.iter();
    while let Some(w) = words.next() {
        if w == "--threads" || w == "--config" {
            words.next();
            continue;
        }
        if w.starts_with("--threads=") || w.starts_with("--config=") {
            continue;
        }
        match cmd.find_subcommand(w) {
            Some(sub) if w != "help" => cmd = sub.clone(),
            // `help` is clap's word only where a subcommand could stand: after `scene info`
            // it is a path.
            _ => return w == "help" && cmd.has_subcommands(),
        }
    }
    false
}

/// The flags a config file gave (`origins` as in [`Applied::origins`]) that `message` names
/// as whole flags (`--step`, not the `--step` of `--step-size`), with where each came from.
pub fn named_in<'a>(origins: &'a [(String, String)], message: &str) -> Vec<(&'a str, &'a str)> {
    origins
        .iter()
        .filter(|(flag, _)| {
            message.match_indices(flag.as_str()).any(|(at, _)| {
                !message[at + flag.len()..]
                    .starts_with(|c: char| c.is_ascii_alphanumeric() || c == '-' || c == '_')
            })
        })
        .map(|(flag, origin)| (flag.as_str(), origin.as_str()))
        .collect()
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

/// A config file's flags for a command line.
#[derive(Debug)]
pub struct Applied {
    /// The flags to add, each `--flag=value` (a bare `--flag` for a boolean `true`), so that a
    /// value starting with `-` stays a value.
    pub added: Vec<String>,
    /// Where each added flag came from (a boolean flag set `false`, so not added, has none).
    pub origins: Origins,
    /// The file's flags left out because a typed flag cannot go with them, each said in words
    /// (the typed flag wins, and the user should know what it displaced).
    pub left_out: Vec<String>,
}

impl Applied {
    /// `argv` with the added flags after the typed ones, before a typed `--` (after which
    /// every word is a positional argument).
    pub fn argv<T: Clone + From<String> + AsRef<std::ffi::OsStr>>(&self, argv: &[T]) -> Vec<T> {
        let at = argv
            .iter()
            .position(|a| a.as_ref() == "--")
            .unwrap_or(argv.len());
        let mut out = argv[..at].to_vec();
        out.extend(self.added.iter().cloned().map(T::from));
        out.extend_from_slice(&argv[at..]);
        out
    }
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

/// The flags of `text`'s tables for `path` that `argv` does not give: the command's own table,
/// then the global flags of its groups' tables (`[data] threads = 1` for every `data`
/// command), then the keys outside every table (the global flags); the first to give a flag
/// wins. A boolean `true` adds the bare flag and `false` nothing, on flags that take no
/// value; a flag that takes one gets the word. A flag the command line gives is not added, nor
/// one that cannot go with a flag it gives ([`Applied::left_out`] says which).
///
/// # Errors
///
/// The text is not TOML (the error names the line); a table that names no command of `C`, a
/// key that names no flag of its table's command, the same flag spelt two ways in one table,
/// or a value that is a table, a date or an array of tables (each named with the file,
/// wherever it is in the file).
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
    // The tables along the path, the command's own first.
    let mut tables = vec![(&root, String::new())];
    for (k, name) in path.iter().enumerate() {
        let Some(t) = tables
            .last()
            .and_then(|(t, _)| t.get(name.as_str()))
            .and_then(toml::Value::as_table)
        else {
            break;
        };
        tables.push((t, format!("[{}] ", path[..=k].join("."))));
    }
    let (root_table, root_name) = tables.remove(0);
    tables.reverse();
    tables.push((root_table, root_name));
    let leaf = path
        .iter()
        .try_fold(cmd.clone(), |c, name| c.find_subcommand(name).cloned());
    // Only the words before a typed `--` are flags.
    let flags_end = argv.iter().position(|a| a == "--").unwrap_or(argv.len());
    let typed: Vec<&str> = argv[..flags_end]
        .iter()
        .filter_map(|a| a.strip_prefix("--"))
        .map(|a| a.split('=').next().unwrap_or(a))
        .collect();
    // A flag the command line gives, or one it gives that cannot go with this flag (the
    // typed `--scale-points` overrides a file's `scale`, as the typed flag wins anywhere).
    let conflicting = |name: &str| {
        leaf.as_ref()
            .and_then(|leaf| typed.iter().find(|t| conflict(leaf, name, t)))
            .copied()
    };
    // Whether the command's flag `name` takes a value (a global one: the root's).
    let takes_value = |name: &str| {
        leaf.iter()
            .chain(std::iter::once(&cmd))
            .flat_map(|c| c.get_arguments())
            .find(|a| a.get_long() == Some(name))
            .is_some_and(|a| a.get_action().takes_values())
    };
    let mut applied = Applied {
        added: Vec::new(),
        origins: Vec::new(),
        left_out: Vec::new(),
    };
    // The flags some table gave, `false` included: the first table to give a flag wins.
    let mut given = std::collections::BTreeSet::new();
    for (table, name) in &tables {
        for (key, value) in *table {
            if value.is_table() {
                continue;
            }
            let flag_name = key.replace('_', "-");
            let flag = format!("--{flag_name}");
            if typed.contains(&flag_name.as_str()) || !given.insert(flag.clone()) {
                continue;
            }
            let origin = format!("{name}{key}");
            if let Some(typed) = conflicting(&flag_name) {
                applied.left_out.push(format!(
                    "{origin} in {} is left out: it cannot go with the command line's --{typed}",
                    file.display()
                ));
                continue;
            }
            // `check_table` has refused, file-wide, every value no flag takes.
            let text = flag_value(value).unwrap_or_default();
            match value {
                // A `false` leaves the flag out: no message can be about it.
                toml::Value::Boolean(false) if !takes_value(&flag_name) => continue,
                toml::Value::Boolean(true) if !takes_value(&flag_name) => {
                    applied.added.push(flag.clone());
                }
                _ => applied.added.push(format!("{flag}={text}")),
            }
            applied
                .origins
                .push((flag, format!("{origin} in {}", file.display())));
        }
    }
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
    let mut spelt: BTreeMap<String, &str> = BTreeMap::new();
    for (key, value) in table {
        let place = || {
            if at.is_empty() {
                key.clone()
            } else {
                format!("[{}] {key}", at.join("."))
            }
        };
        if !value.is_table() {
            if let Some(other) = spelt.insert(key.replace('_', "-"), key) {
                return Err(Error::format(
                    place(),
                    format!("the same flag as `{other}`: give it once"),
                ));
            }
            if flag_value(value).is_none() {
                return Err(Error::format(
                    place(),
                    "expected a string, number, boolean or list",
                ));
            }
        }
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
    use clap::Parser;

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
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(
            applied.added,
            args("--per-scene=20 --val=0.2"),
            "the command line's --seed wins"
        );
        let demo = args("sage3d demo");
        let applied =
            apply::<crate::Cli>(text, Path::new("c.toml"), &["demo".into()], &demo).unwrap();
        assert_eq!(
            applied.argv(&demo),
            args("sage3d demo --agents=oracle,random")
        );
        // No table for the command: nothing added.
        let nav = args("sage3d nav map S");
        let path = subcommand_path::<crate::Cli>(&nav);
        assert_eq!(
            apply::<crate::Cli>(text, Path::new("c.toml"), &path, &nav)
                .unwrap()
                .argv(&nav),
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
            applied.added,
            Vec::<String>::new(),
            "the file's scale goes with neither typed flag"
        );
        let argv = args("sage3d scene import C --out S --scale-distance 2");
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(
            applied.added,
            Vec::<String>::new(),
            "the typed --scale-distance, alone, still wins"
        );
        let argv = args("sage3d render S --out R --camera cam.json");
        let path = subcommand_path::<crate::Cli>(&argv);
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(
            applied.added,
            Vec::<String>::new(),
            "a camera file sets the pose and size itself"
        );
        assert_eq!(
            applied.left_out,
            [
                "[render] width in c.toml is left out: it cannot go with the command line's --camera",
                "[render] yaw in c.toml is left out: it cannot go with the command line's --camera",
            ]
        );
        let argv = args("sage3d render S --out R");
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(applied.added, args("--width=320 --yaw=30"));
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
        assert_eq!(applied.added, args("--yaw=30 --threads=2"));
        assert_eq!(
            origin_of(&applied.origins, "--yaw <YAW>"),
            Some("[render] yaw in c.toml")
        );
        assert_eq!(origin_of(&applied.origins, "--out <OUT>"), None);
    }

    #[test]
    fn a_flag_set_false_is_left_out_and_named_by_no_note() {
        let argv = args("sage3d splat convert in.ply out.ply");
        let path = subcommand_path::<crate::Cli>(&argv);
        let applied = apply::<crate::Cli>(
            "[splat.convert]\nforce = false\n",
            Path::new("c.toml"),
            &path,
            &argv,
        )
        .unwrap();
        assert!(applied.added.is_empty() && applied.origins.is_empty());
        let message = "out.ply exists; set --force to replace it";
        assert!(named_in(&applied.origins, message).is_empty());
        let applied = apply::<crate::Cli>(
            "[splat.convert]\nforce = true\n",
            Path::new("c.toml"),
            &path,
            &argv,
        )
        .unwrap();
        assert_eq!(applied.added, args("--force"));
        assert_eq!(named_in(&applied.origins, message).len(), 1);
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

    #[test]
    fn file_flags_go_before_a_typed_double_dash_and_keep_values_that_start_with_a_dash() {
        let text = "[render]\nyaw = -30\nout = \"-dash dir\"\nforce = true\n";
        let argv = args("sage3d render -- -dashscene");
        let path = subcommand_path::<crate::Cli>(&argv);
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(
            applied.argv(&argv),
            [
                "sage3d",
                "render",
                "--force",
                "--out=-dash dir",
                "--yaw=-30",
                "--",
                "-dashscene"
            ]
        );
        assert!(crate::Cli::try_parse_from(applied.argv(&argv)).is_ok());
        // A word after `--` is a positional, not a typed flag.
        let argv = args("sage3d render -- --yaw");
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert!(applied.added.contains(&"--yaw=-30".to_string()));
    }

    #[test]
    fn a_boolean_on_a_flag_that_takes_a_value_is_its_word_for_clap_to_judge() {
        let argv = args("sage3d render S --out R");
        let path = subcommand_path::<crate::Cli>(&argv);
        let applied =
            apply::<crate::Cli>("[render]\nyaw = false\n", Path::new("c.toml"), &path, &argv)
                .unwrap();
        assert_eq!(applied.added, args("--yaw=false"));
        let e = crate::Cli::try_parse_from(applied.argv(&argv))
            .err()
            .unwrap();
        assert_eq!(e.kind(), clap::error::ErrorKind::ValueValidation);
    }

    #[test]
    fn a_group_table_gives_its_commands_the_global_flags() {
        let text = "threads = 4\n[data]\nthreads = 1\n[data.render]\nlimit = 2\n";
        let argv = args("sage3d data render D --out O");
        let path = subcommand_path::<crate::Cli>(&argv);
        let applied = apply::<crate::Cli>(text, Path::new("c.toml"), &path, &argv).unwrap();
        assert_eq!(applied.added, args("--limit=2 --threads=1"));
        assert_eq!(
            origin_of(&applied.origins, "--threads <THREADS>"),
            Some("[data] threads in c.toml")
        );
    }

    #[test]
    fn one_flag_spelt_twice_and_values_no_flag_takes_are_errors_wherever_they_are() {
        let check = |text: &str| {
            apply::<crate::Cli>(
                text,
                Path::new("c.toml"),
                &["demo".into()],
                &args("sage3d demo"),
            )
            .unwrap_err()
            .to_string()
        };
        let e = check("[data.build]\nper_scene = 1\nper-scene = 2\n");
        assert!(
            e.contains("[data.build] per_scene") && e.contains("give it once"),
            "{e}"
        );
        let e = check("[render]\nyaw = 1979-05-27\n");
        assert!(
            e.contains("[render] yaw") && e.contains("expected a string"),
            "{e}"
        );
        let e = check("[[render]]\nyaw = 1\n");
        assert!(e.contains("render: expected a string"), "{e}");
    }

    #[test]
    fn help_is_asked_for_by_its_flags_or_word_and_not_by_a_value() {
        let asks = |s: &str| asks_for_help::<crate::Cli>(&args(s));
        for yes in [
            "sage3d --config c.toml --help",
            "sage3d --config c.toml data build -h",
            "sage3d --config c.toml help",
            "sage3d --threads 2 --config=c.toml data help build",
            "sage3d --config c.toml -V",
        ] {
            assert!(asks(yes), "{yes}");
        }
        for no in [
            "sage3d --config c.toml data build S --out help",
            "sage3d --config help data build S",
            "sage3d --config c.toml render S -- --help",
            "sage3d --config c.toml demo",
            "sage3d --config c.toml scene info help",
        ] {
            assert!(!asks(no), "{no}");
        }
    }

    #[test]
    fn an_error_naming_a_file_flag_is_told_where_it_came_from() {
        let origins = vec![
            (
                "--step".to_string(),
                "[data.render] step in c.toml".to_string(),
            ),
            ("--seed".to_string(), "seed in c.toml".to_string()),
        ];
        assert_eq!(
            named_in(&origins, "--answers navila needs --step in whole cm"),
            [("--step", "[data.render] step in c.toml")]
        );
        assert!(named_in(&origins, "--step-size and --seeds are wrong").is_empty());
    }
}
