//! ARCHITECTURE.md's dependency list matches the library crates' Cargo.toml files: each
//! `- \`crate\` → ...` line names exactly the workspace crates in that crate's
//! `[dependencies]`.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::collections::BTreeSet;
use std::path::Path;

/// The workspace crates (`sd-*`) in the `[dependencies]` table of a Cargo.toml.
fn workspace_deps(cargo_toml: &str) -> BTreeSet<String> {
    let doc: toml::Table = cargo_toml.parse().expect("Cargo.toml parses");
    doc.get("dependencies")
        .and_then(|d| d.as_table())
        .map(|t| t.keys().filter(|k| k.starts_with("sd-")).cloned().collect())
        .unwrap_or_default()
}

#[test]
fn architecture_dependency_list_matches_cargo_toml() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("..");
    let arch = std::fs::read_to_string(root.join("ARCHITECTURE.md")).unwrap();
    let mut checked = 0;
    for line in arch.lines() {
        let Some(rest) = line.strip_prefix("- `") else {
            continue;
        };
        let Some((krate, deps)) = rest.split_once("` → ") else {
            continue;
        };
        let listed: BTreeSet<String> = deps
            .split(", ")
            .map(|d| d.trim().trim_matches('`').to_string())
            .filter(|d| d != "none")
            .collect();
        let toml = std::fs::read_to_string(root.join(krate).join("Cargo.toml")).unwrap();
        assert_eq!(
            listed,
            workspace_deps(&toml),
            "ARCHITECTURE.md's line for {krate} disagrees with its Cargo.toml"
        );
        checked += 1;
    }
    assert_eq!(checked, 9, "every library crate has its line");
}
