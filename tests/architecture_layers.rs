//! The crate's modules import downward only: every `crate::m` path in a top-level module must
//! name a module of a strictly lower layer of the table in `docs/architecture.md`, and every
//! top-level module must be in that table. A strict order of layers rules out import cycles.

mod common;

use std::collections::BTreeMap;
use std::path::Path;

/// The layer of each module named in the "Layers" table of `docs/architecture.md`.
fn layers_from_doc(doc: &str) -> BTreeMap<String, u32> {
    let mut layers = BTreeMap::new();
    let section = doc
        .split("## Layers")
        .nth(1)
        .expect("docs/architecture.md has a `## Layers` section");
    let section = section.split("\n## ").next().unwrap_or(section);
    for line in section.lines() {
        let cells: Vec<&str> = line.split('|').map(str::trim).collect();
        if cells.len() < 4 {
            continue;
        }
        let Ok(layer) = cells[1].parse::<u32>() else {
            continue;
        };
        for name in cells[2].split('`').skip(1).step_by(2) {
            let previous = layers.insert(name.to_string(), layer);
            assert!(
                previous.is_none(),
                "`{name}` is listed twice in the layer table"
            );
        }
    }
    assert!(
        !layers.is_empty(),
        "no layer rows found in docs/architecture.md"
    );
    layers
}

/// The code of a source file without `//` comments (doc comments cite modules freely).
fn code_of(text: &str) -> String {
    text.lines()
        .map(|l| l.split("//").next().unwrap_or(""))
        .collect::<Vec<_>>()
        .join("\n")
}

/// The top-level modules named by `crate::m` and `crate::{a, b::c}` paths in `code`.
fn crate_imports(code: &str) -> Vec<String> {
    let mut out = Vec::new();
    for (i, _) in code.match_indices("crate::") {
        let rest = &code[i + "crate::".len()..];
        if let Some(group) = rest.strip_prefix('{') {
            let end = group.find('}').unwrap_or(group.len());
            for item in group[..end].split(',') {
                let name: String = item
                    .trim()
                    .chars()
                    .take_while(|c| c.is_alphanumeric() || *c == '_')
                    .collect();
                if !name.is_empty() {
                    out.push(name);
                }
            }
        } else {
            let name: String = rest
                .chars()
                .take_while(|c| c.is_alphanumeric() || *c == '_')
                .collect();
            if !name.is_empty() {
                out.push(name);
            }
        }
    }
    out
}

fn rust_files(dir: &Path, out: &mut Vec<std::path::PathBuf>) {
    for entry in std::fs::read_dir(dir).expect("read src/") {
        let path = entry.expect("directory entry").path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

#[test]
fn modules_import_only_from_lower_layers() {
    let root = common::files::repo_path("");
    let doc = std::fs::read_to_string(root.join("docs/architecture.md"))
        .expect("read docs/architecture.md");
    let layers = layers_from_doc(&doc);
    let src = root.join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut problems = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for file in &files {
        let rel = file.strip_prefix(&src).expect("inside src/");
        let top = rel
            .components()
            .next()
            .and_then(|c| c.as_os_str().to_str())
            .map(|s| s.trim_end_matches(".rs").to_string())
            .expect("a file name");
        if top == "lib" || top == "main" {
            continue;
        }
        seen.insert(top.clone());
        let Some(&own) = layers.get(&top) else {
            problems.push(format!(
                "module `{top}` is not in the layer table of docs/architecture.md"
            ));
            continue;
        };
        let text = std::fs::read_to_string(file).expect("read a source file");
        for dep in crate_imports(&code_of(&text)) {
            if dep == top {
                continue;
            }
            match layers.get(&dep) {
                Some(&layer) if layer < own => {}
                Some(&layer) => problems.push(format!(
                    "{}: `{top}` (layer {own}) imports `{dep}` (layer {layer})",
                    rel.display()
                )),
                None => problems.push(format!(
                    "{}: `{top}` imports `{dep}`, which is not in the layer table",
                    rel.display()
                )),
            }
        }
    }
    for name in layers.keys() {
        if !seen.contains(name) {
            problems.push(format!(
                "the layer table names `{name}`, which is not a module of src/"
            ));
        }
    }
    assert!(
        problems.is_empty(),
        "layering violations:\n{}",
        problems.join("\n")
    );
}

#[test]
fn the_checker_sees_grouped_and_nested_imports() {
    let code = code_of(
        "use crate::{math::Vec3, spectrum};\nlet x = crate::grid::Node::Tile; // crate::cli\n",
    );
    assert_eq!(crate_imports(&code), ["math", "spectrum", "grid"]);
    let layers = layers_from_doc("## Layers\n| layer | modules | job |\n|---|---|---|\n| 1 | `a`, `b` | x |\n| 2 | `c` | y |\n## Next\n| 3 | `d` | z |\n");
    assert_eq!(layers.len(), 3);
    assert_eq!(layers["c"], 2);
}
