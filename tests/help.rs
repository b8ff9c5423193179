//! Every command's `--help` teaches with an example, and the models its examples name exist.

use std::path::Path;
use std::process::Command;

fn help(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_dynid"))
        .args(args)
        .arg("--help")
        .output()
        .unwrap();
    assert!(out.status.success(), "{args:?}");
    String::from_utf8(out.stdout).unwrap()
}

/// The subcommands listed by `dynid --help` (so that a new command is covered).
fn commands() -> Vec<String> {
    let top = help(&[]);
    let list = top
        .split("Commands:")
        .nth(1)
        .expect("a Commands section")
        .split("\n\n")
        .next()
        .unwrap();
    list.lines()
        .filter_map(|l| l.split_whitespace().next())
        .filter(|c| *c != "help")
        .map(str::to_string)
        .collect()
}

#[test]
fn every_command_has_an_example_that_names_real_models() {
    let cmds = commands();
    assert!(cmds.len() >= 7, "{cmds:?}");
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    for c in &cmds {
        let text = help(&[c]);
        assert!(
            text.contains("Example"),
            "`dynid {c} --help` has no example:\n{text}"
        );
        for word in text.split(|ch: char| ch.is_whitespace() || ch == '`') {
            if let Some(rest) = word.strip_prefix("models/") {
                let name: String = rest
                    .chars()
                    .take_while(|ch| ch.is_alphanumeric() || *ch == '_' || *ch == '.')
                    .collect();
                let name = name.trim_end_matches('.');
                assert!(
                    root.join("models").join(name).is_file(),
                    "`dynid {c} --help` names models/{name}, which does not exist"
                );
            }
        }
    }
}
