//! The core crate's layers (docs/architecture.md, "Layers of the core crate"): every
//! non-comment `crate::<folder>` path in the crate's sources (a `use` or a path in code;
//! `//`, `///` and `//!` lines are comments, so doc links are allowed) must name the
//! file's own layer or one below it, and no two folders may import each other (a
//! circle). A failure names the file and line.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The layers, bottom up: a folder (or a top-level file, named without `.rs`) and its
/// rank in docs/architecture.md. A folder imports its own rank and those below, never
/// above. A new folder is one entry here (and one line of the doc).
const RANKS: &[(&str, u32)] = &[
    ("cancel", 0),
    ("error", 0),
    ("model", 0),
    ("numerics", 0),
    ("io", 1),
    ("vision", 2),
    ("calib", 3),
    ("stripe_model", 3),
    ("reconstruct", 4),
    ("pipeline", 5),
];

/// Circles the doc allows: `error.rs` and `model/` share the base, the error type
/// carries the model's `QualityFailure` and the model returns the crate's `Result`.
const BASE_CIRCLES: &[(&str, &str)] = &[("error", "model")];

/// One reference: the file (relative to `src/`), its line, the folder it names.
struct Reference {
    file: String,
    line: usize,
    target: String,
}

fn rank(folder: &str) -> Option<u32> {
    RANKS.iter().find(|(f, _)| *f == folder).map(|(_, r)| *r)
}

/// The `.rs` files under `dir`, sorted.
fn sources(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for p in entries {
        if p.is_dir() {
            sources(&p, out);
        } else if p.extension().is_some_and(|e| e == "rs") {
            out.push(p);
        }
    }
}

/// The layer a file belongs to: its first folder under `src/`, or a top-level file's
/// name without `.rs`.
fn layer_of(rel: &str) -> String {
    let first = rel.split('/').next().unwrap();
    first.trim_end_matches(".rs").to_string()
}

/// A line without its trailing `//` comment (a `//` inside a string literal is kept).
fn code_of(line: &str) -> &str {
    let mut in_str = false;
    let mut prev = ' ';
    for (i, c) in line.char_indices() {
        if c == '"' && prev != '\\' {
            in_str = !in_str;
        }
        if !in_str && c == '/' && prev == '/' {
            return &line[..i - 1];
        }
        prev = c;
    }
    line
}

/// The leading identifier of `s`.
fn ident(s: &str) -> &str {
    let end = s
        .find(|c: char| !(c.is_alphanumeric() || c == '_'))
        .unwrap_or(s.len());
    &s[..end]
}

/// The crate-root names `lib.rs` re-exports (`pub use model::board::{Board, ...}`), each
/// with the folder it comes from.
fn root_names(lib: &str) -> BTreeMap<String, String> {
    let mut names = BTreeMap::new();
    for line in lib.lines().map(str::trim) {
        let Some(path) = line.strip_prefix("pub use ") else {
            continue;
        };
        let folder = ident(path).to_string();
        let rest = path.trim_end_matches(';');
        let items = match rest.find('{') {
            Some(b) => rest[b + 1..].trim_end_matches('}').to_string(),
            None => rest.rsplit("::").next().unwrap().to_string(),
        };
        for item in items.split(',') {
            let name = ident(item.trim());
            if !name.is_empty() {
                names.insert(name.to_string(), folder.clone());
            }
        }
    }
    names
}

/// The text inside the `{...}` group `first` opens, continued over the `next` lines
/// (their code) up to its closing brace.
fn brace_group(first: &str, next: &[&str]) -> String {
    let mut group = String::new();
    let mut depth = 0;
    for l in std::iter::once(first).chain(next.iter().map(|l| code_of(l))) {
        for c in l.chars() {
            match c {
                '{' => depth += 1,
                '}' => depth -= 1,
                _ => {}
            }
            if depth == 0 {
                return group;
            }
            if depth > 1 || c != '{' {
                group.push(c);
            }
        }
        group.push(' ');
    }
    group
}

/// The comma-separated items of a group's text, nested groups kept whole.
fn top_level_items(group: &str) -> Vec<String> {
    let mut depth = 0;
    let mut items = vec![String::new()];
    for c in group.chars() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                items.push(String::new());
                continue;
            }
            _ => {}
        }
        items.last_mut().unwrap().push(c);
    }
    items
}

/// Every folder named by a `crate::` path in the code of `text` (comments left out), with
/// its line; `crate::{a::X, B}` names each item's first segment, a crate-root name its
/// folder (`roots`). Names that are neither a layer nor a root name are returned as they
/// are (the test then asks for them to be ranked).
fn references(rel: &str, text: &str, roots: &BTreeMap<String, String>) -> Vec<Reference> {
    let lines: Vec<&str> = text.lines().collect();
    let mut out = Vec::new();
    let mut push = |line: usize, name: &str| {
        let target = roots.get(name).cloned().unwrap_or_else(|| name.to_string());
        out.push(Reference {
            file: rel.to_string(),
            line,
            target,
        });
    };
    for (i, raw) in lines.iter().enumerate() {
        if raw.trim_start().starts_with("//") {
            continue;
        }
        let code = code_of(raw);
        let mut from = 0;
        while let Some(k) = code[from..].find("crate::") {
            let at = from + k;
            from = at + "crate::".len();
            // `stripecal_crate::` or `$crate::` are not this crate's paths
            let before = code[..at].chars().next_back();
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == '$') {
                continue;
            }
            let rest = &code[from..];
            if rest.starts_with('{') {
                for item in top_level_items(&brace_group(rest, &lines[i + 1..])) {
                    let name = ident(item.trim());
                    if !name.is_empty() {
                        push(i + 1, name);
                    }
                }
            } else {
                let name = ident(rest);
                if !name.is_empty() {
                    push(i + 1, name);
                }
            }
        }
    }
    out
}

#[test]
fn no_layer_imports_a_layer_above_it_and_no_folders_import_each_other() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let roots = root_names(&std::fs::read_to_string(src.join("lib.rs")).unwrap());
    let mut files = Vec::new();
    sources(&src, &mut files);
    let mut problems = Vec::new();
    // (from, to) -> the first file:line of such an import
    let mut edges: BTreeMap<(String, String), String> = BTreeMap::new();
    for path in &files {
        let rel = path
            .strip_prefix(&src)
            .unwrap()
            .to_string_lossy()
            .replace('\\', "/");
        if rel == "lib.rs" {
            // the crate root declares and re-exports every layer
            continue;
        }
        let layer = layer_of(&rel);
        let Some(own) = rank(&layer) else {
            problems.push(format!(
                "{rel}: the layer `{layer}` has no rank: add it to RANKS (tests/it/layers.rs) \
                 and to docs/architecture.md"
            ));
            continue;
        };
        let text = std::fs::read_to_string(path).unwrap();
        for r in references(&rel, &text, &roots) {
            if r.target == layer {
                continue;
            }
            let Some(theirs) = rank(&r.target) else {
                problems.push(format!(
                    "{}:{}: `crate::{}` is not a ranked layer: add it to RANKS \
                     (tests/it/layers.rs) and to docs/architecture.md",
                    r.file, r.line, r.target
                ));
                continue;
            };
            if theirs > own {
                problems.push(format!(
                    "{}:{}: `{layer}` (rank {own}) imports `{}` (rank {theirs}), a layer above it",
                    r.file, r.line, r.target
                ));
            }
            edges
                .entry((layer.clone(), r.target.clone()))
                .or_insert_with(|| format!("{}:{}", r.file, r.line));
        }
    }
    let allowed: BTreeSet<(&str, &str)> = BASE_CIRCLES
        .iter()
        .flat_map(|&(a, b)| [(a, b), (b, a)])
        .collect();
    for ((a, b), at) in &edges {
        if a < b && !allowed.contains(&(a.as_str(), b.as_str())) {
            if let Some(back) = edges.get(&(b.clone(), a.clone())) {
                problems.push(format!(
                    "a circle: `{a}` imports `{b}` ({at}) and `{b}` imports `{a}` ({back})"
                ));
            }
        }
    }
    assert!(
        problems.is_empty(),
        "layer violations (docs/architecture.md):\n{}",
        problems.join("\n")
    );
}

#[test]
fn references_skip_comments_and_read_groups() {
    let roots = root_names("pub use model::board::{Board, BoardKind};\npub use error::Result;");
    let text = "//! [`crate::pipeline`]\n/// crate::io\nuse crate::{Board, numerics::tls,\n    vision::x};\nlet a = crate::calib::f(); // crate::pipeline\n";
    let found: Vec<(usize, String)> = references("x.rs", text, &roots)
        .into_iter()
        .map(|r| (r.line, r.target))
        .collect();
    assert_eq!(
        found,
        vec![
            (3, "model".to_string()),
            (3, "numerics".to_string()),
            (3, "vision".to_string()),
            (5, "calib".to_string()),
        ]
    );
}
