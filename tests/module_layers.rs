//! The house's module graph, read from the sources (`use crate::…`,
//! `super::…` and inline `crate::…` paths outside `#[cfg(test)]` code and
//! comments):
//! - every top-level module of the library imports only from the layers
//!   below it ([`LAYERS`]): nothing imports from `system`, `error` sits
//!   above the lower modules it wraps, `eval` and `dataset` import nothing
//!   from the SLAM core;
//! - no circle between files, in the library or in the CLI (an item used
//!   through a folder's `mod.rs` re-export counts as used from the file
//!   that defines it).

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

/// The library's top-level modules, bottom layer first. A module may
/// import from modules of lower layers only (not from its own layer).
const LAYERS: &[&[&str]] = &[
    &["stats"],
    &["features", "optim", "dataset", "eval"],
    &["geometry", "settings", "matching", "place", "map"],
    &["camera"],
    &["storage"],
    &["error"],
    &["tracking", "mapping"],
    &["loop_closing"],
    &["system"],
    &["ffi"],
];

/// Test-only modules, outside the layering.
const TEST_ONLY: &[&str] = &["test_world"];

fn source_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = fs::read_dir(dir) else {
        panic!("cannot list {}", dir.display());
    };
    let mut entries: Vec<PathBuf> = entries.filter_map(|e| e.ok().map(|e| e.path())).collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            source_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The file's code without comments, `#[cfg(test)]` items and test modules.
fn production_code(text: &str) -> String {
    let mut out = String::new();
    let mut skip_item = false;
    let mut depth_at_skip: Option<i64> = None;
    let mut depth: i64 = 0;
    for line in text.lines() {
        let trimmed = line.trim_start();
        if trimmed.starts_with("//") {
            continue;
        }
        if trimmed.starts_with("#[cfg(test)]") {
            skip_item = true;
            continue;
        }
        let opens = line.matches('{').count() as i64;
        let closes = line.matches('}').count() as i64;
        if skip_item && depth_at_skip.is_none() {
            // The item after #[cfg(test)]: one line (`use …;`) or a block.
            if opens > closes {
                depth_at_skip = Some(depth);
            } else {
                skip_item = false;
            }
            depth += opens - closes;
            continue;
        }
        depth += opens - closes;
        if let Some(d) = depth_at_skip {
            if depth <= d {
                depth_at_skip = None;
                skip_item = false;
            }
            continue;
        }
        // Drop a trailing comment.
        let code = match line.find("//") {
            Some(i) if !line[..i].contains('"') => &line[..i],
            _ => line,
        };
        out.push_str(code);
        out.push('\n');
    }
    out
}

/// Expands a use tree (`a::{b, c::{d, e as f}}`) into paths.
fn expand_use(tree: &str, prefix: &[String], out: &mut Vec<Vec<String>>) {
    let tree = tree.trim();
    if tree.is_empty() {
        return;
    }
    if let Some(open) = tree.find('{') {
        let head = tree[..open].trim().trim_end_matches("::");
        let mut path = prefix.to_vec();
        path.extend(
            head.split("::")
                .filter(|s| !s.is_empty())
                .map(|s| s.trim().to_string()),
        );
        let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
        let mut level = 0;
        let mut start = 0;
        for (i, ch) in inner.char_indices() {
            match ch {
                '{' => level += 1,
                '}' => level -= 1,
                ',' if level == 0 => {
                    expand_use(&inner[start..i], &path, out);
                    start = i + 1;
                }
                _ => {}
            }
        }
        expand_use(&inner[start..], &path, out);
    } else {
        let name = tree.split(" as ").next().unwrap_or(tree).trim();
        let mut path = prefix.to_vec();
        path.extend(name.split("::").map(|s| s.trim().to_string()));
        out.push(path);
    }
}

/// Every path the code names from `crate`, `super` or `self` (use trees
/// expanded, inline paths up to their last `::` segment).
fn named_paths(code: &str) -> Vec<Vec<String>> {
    let mut out = Vec::new();
    let mut rest = code;
    // use statements (possibly several lines)
    while let Some(i) = rest.find("use ") {
        let before = rest[..i].chars().last();
        let after = &rest[i + 4..];
        rest = after;
        if before.is_some_and(|c| c.is_alphanumeric() || c == '_') {
            continue;
        }
        let Some(end) = after.find(';') else { break };
        let tree = after[..end].trim();
        if tree.starts_with("crate::") || tree.starts_with("super::") || tree.starts_with("self::")
        {
            expand_use(tree, &[], &mut out);
        }
    }
    // inline paths
    for root in ["crate::", "super::"] {
        let mut rest = code;
        while let Some(i) = rest.find(root) {
            let before = rest[..i].chars().last();
            let tail = &rest[i..];
            rest = &rest[i + root.len()..];
            if before.is_some_and(|c| c.is_alphanumeric() || c == '_' || c == ':') {
                continue;
            }
            let end = tail
                .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .unwrap_or(tail.len());
            let path: Vec<String> = tail[..end]
                .split("::")
                .filter(|s| !s.is_empty())
                .map(str::to_string)
                .collect();
            out.push(path);
        }
    }
    out
}

/// One crate's files by module path (`["tracking", "pose"]`).
struct CrateFiles {
    root: PathBuf,
    modules: BTreeMap<Vec<String>, PathBuf>,
}

impl CrateFiles {
    fn new(root: &Path, files: &[PathBuf], root_file: &str) -> Self {
        let mut modules = BTreeMap::new();
        for f in files {
            let Ok(rel) = f.strip_prefix(root) else {
                continue;
            };
            let mut parts: Vec<String> = rel
                .components()
                .map(|c| c.as_os_str().to_string_lossy().into_owned())
                .collect();
            let Some(last) = parts.pop() else { continue };
            if last != "mod.rs" && !(parts.is_empty() && last == root_file) {
                parts.push(last.trim_end_matches(".rs").to_string());
            }
            modules.insert(parts, f.clone());
        }
        Self {
            root: root.to_path_buf(),
            modules,
        }
    }

    fn is_folder(&self, module: &[String]) -> bool {
        let mut dir = self.root.clone();
        dir.extend(module);
        module.is_empty() || dir.join("mod.rs").is_file()
    }

    /// The file that defines what `path` (absolute) names, following a
    /// folder's `pub use` re-exports.
    fn resolve(&self, path: &[String], depth: usize) -> Option<PathBuf> {
        let mut module: Vec<String> = Vec::new();
        let mut i = 0;
        while i < path.len() {
            let mut next = module.clone();
            next.push(path[i].clone());
            if self.modules.contains_key(&next) {
                module = next;
                i += 1;
            } else {
                break;
            }
        }
        let file = self.modules.get(&module)?.clone();
        if i < path.len() && depth < 8 && self.is_folder(&module) {
            // An item of a folder: find the re-export that names it.
            let text = fs::read_to_string(&file).ok()?;
            let code = production_code(&text);
            for line in code.split(';') {
                let line = line.trim();
                let Some(tree) = line
                    .strip_prefix("pub use ")
                    .or_else(|| line.strip_prefix("pub(crate) use "))
                    .or_else(|| line.strip_prefix("pub(super) use "))
                else {
                    continue;
                };
                let mut paths = Vec::new();
                expand_use(tree, &[], &mut paths);
                let raw = tree.to_string();
                for p in paths {
                    let last = p.last().cloned().unwrap_or_default();
                    let alias_hit = raw.contains(&format!("{last} as {}", path[i]));
                    if last == path[i] || alias_hit {
                        let absolute = self.absolute(&module, true, &p)?;
                        return self.resolve(&absolute, depth + 1).or(Some(file));
                    }
                }
            }
        }
        Some(file)
    }

    /// `path` as named in module `from` (a folder's `mod.rs` when
    /// `from_folder`), made absolute.
    fn absolute(&self, from: &[String], from_folder: bool, path: &[String]) -> Option<Vec<String>> {
        let mut base: Vec<String> = from.to_vec();
        let mut rest = path;
        match path.first().map(String::as_str) {
            Some("crate") => {
                base.clear();
                rest = &path[1..];
            }
            Some("super") => {
                // `super` of a file is its folder; of a folder, its parent.
                base.pop()?;
                rest = &path[1..];
                while rest.first().is_some_and(|s| s == "super") {
                    base.pop()?;
                    rest = &rest[1..];
                }
            }
            Some("self") => rest = &path[1..],
            _ => {
                // A plain path inside a folder's `pub use`: a child module.
                if !from_folder {
                    base.pop();
                }
            }
        }
        base.extend(rest.iter().cloned());
        Some(base)
    }

    /// File → files it imports from (itself and the crate root excluded).
    fn edges(&self) -> BTreeMap<PathBuf, BTreeSet<PathBuf>> {
        let mut edges: BTreeMap<PathBuf, BTreeSet<PathBuf>> = BTreeMap::new();
        for (module, file) in &self.modules {
            let Ok(text) = fs::read_to_string(file) else {
                panic!("cannot read {}", file.display());
            };
            let from_folder = self.is_folder(module);
            let targets = edges.entry(file.clone()).or_default();
            for path in named_paths(&production_code(&text)) {
                let Some(absolute) = self.absolute(module, from_folder, &path) else {
                    continue;
                };
                if let Some(target) = self.resolve(&absolute, 0) {
                    if &target != file && target != self.modules[&Vec::new()] {
                        targets.insert(target);
                    }
                }
            }
        }
        edges
    }
}

/// Circles of the graph (strongly connected sets of more than one file),
/// folders' `mod.rs` excluded (they declare and re-export their children).
fn circles(edges: &BTreeMap<PathBuf, BTreeSet<PathBuf>>) -> Vec<Vec<PathBuf>> {
    let keep = |p: &PathBuf| p.file_name().is_some_and(|n| n != "mod.rs");
    let nodes: Vec<&PathBuf> = edges.keys().filter(|p| keep(p)).collect();
    let reach = |from: &PathBuf| {
        let mut seen = BTreeSet::new();
        let mut stack = vec![from.clone()];
        while let Some(n) = stack.pop() {
            for t in edges.get(&n).into_iter().flatten() {
                if keep(t) && seen.insert(t.clone()) {
                    stack.push(t.clone());
                }
            }
        }
        seen
    };
    let reachable: BTreeMap<&PathBuf, BTreeSet<PathBuf>> =
        nodes.iter().map(|n| (*n, reach(n))).collect();
    let mut out: Vec<Vec<PathBuf>> = Vec::new();
    let mut done = BTreeSet::new();
    for n in &nodes {
        if done.contains(*n) || !reachable[n].contains(*n) {
            continue;
        }
        let circle: Vec<PathBuf> = nodes
            .iter()
            .filter(|m| reachable[n].contains(**m) && reachable[*m].contains(*n))
            .map(|m| (*m).clone())
            .collect();
        done.extend(circle.iter().cloned());
        out.push(circle);
    }
    out
}

fn library() -> (CrateFiles, Vec<PathBuf>) {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    source_files(&root, &mut files);
    files.retain(|f| !f.starts_with(root.join("bin")));
    (CrateFiles::new(&root, &files, "lib.rs"), files)
}

fn top_module(root: &Path, file: &Path) -> String {
    let rel = file.strip_prefix(root).unwrap_or(file);
    let first = rel
        .components()
        .next()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .unwrap_or_default();
    first.trim_end_matches(".rs").to_string()
}

fn layer_of(module: &str) -> Option<usize> {
    LAYERS.iter().position(|layer| layer.contains(&module))
}

#[test]
fn no_module_imports_from_its_own_layer_or_one_above() {
    let (krate, _) = library();
    let mut wrong = Vec::new();
    let mut arrows = 0;
    for (from, targets) in krate.edges() {
        let a = top_module(&krate.root, &from);
        if a == "lib" || TEST_ONLY.contains(&a.as_str()) {
            continue;
        }
        let Some(la) = layer_of(&a) else {
            panic!(
                "module {a} ({}) is in no layer: add it to LAYERS",
                from.display()
            );
        };
        for to in targets {
            let b = top_module(&krate.root, &to);
            if a == b || TEST_ONLY.contains(&b.as_str()) {
                continue;
            }
            arrows += 1;
            let Some(lb) = layer_of(&b) else {
                panic!("module {b} is in no layer: add it to LAYERS");
            };
            if lb >= la {
                wrong.push(format!(
                    "{} → {} ({a} layer {la} → {b} layer {lb})",
                    from.display(),
                    to.display()
                ));
            }
        }
    }
    eprintln!("{arrows} arrows between top-level modules checked");
    assert!(
        arrows > 100,
        "the parser found only {arrows} arrows: it is broken"
    );
    assert!(
        wrong.is_empty(),
        "imports that run sideways or up:\n{}",
        wrong.join("\n")
    );
}

#[test]
fn no_circle_between_files_of_the_library() {
    let (krate, files) = library();
    let edges = krate.edges();
    assert_eq!(edges.len(), files.len());
    let inside: usize = edges.values().map(BTreeSet::len).sum();
    eprintln!("{} files, {inside} file-to-file arrows", files.len());
    assert!(
        inside > 300,
        "the parser found only {inside} arrows: it is broken"
    );
    let found = circles(&edges);
    assert!(found.is_empty(), "circles between files: {found:#?}");
}

#[test]
fn no_circle_between_files_of_the_cli() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).join("src/bin/spslam");
    let mut files = Vec::new();
    source_files(&root, &mut files);
    let krate = CrateFiles::new(&root, &files, "main.rs");
    let edges = krate.edges();
    let found = circles(&edges);
    assert!(found.is_empty(), "circles between files: {found:#?}");
}

#[test]
fn the_parser_sees_a_planted_circle_through_a_re_export() {
    // Guards the guard: a known cycle in a scratch crate is found.
    let dir = std::env::temp_dir().join(format!("spslam_layers_{}", std::process::id()));
    let src = dir.join("src");
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(src.join("tracking")).unwrap_or_else(|e| panic!("{e}"));
    let write = |p: &str, t: &str| fs::write(src.join(p), t).unwrap_or_else(|e| panic!("{e}"));
    write("lib.rs", "pub mod tracking;\n");
    write(
        "tracking/mod.rs",
        "mod a;\nmod b;\npub use a::Alpha;\npub use b::{Beta, beta as renamed};\n",
    );
    write(
        "tracking/a.rs",
        "// use super::Beta; (a comment)\nuse super::Beta;\npub struct Alpha;\n",
    );
    write(
        "tracking/b.rs",
        "pub struct Beta(crate::tracking::Alpha);\npub fn beta() {}\n#[cfg(test)]\nmod tests {\n    use super::super::a::Alpha;\n}\n",
    );
    let mut files = Vec::new();
    source_files(&src, &mut files);
    let krate = CrateFiles::new(&src, &files, "lib.rs");
    let edges = krate.edges();
    let found = circles(&edges);
    let _ = fs::remove_dir_all(&dir);
    assert_eq!(found.len(), 1, "{edges:#?}");
    assert_eq!(found[0].len(), 2, "{found:#?}");
    assert_eq!(layer_of("system"), Some(LAYERS.len() - 2));
    assert!(layer_of("error") > layer_of("storage"));
}
