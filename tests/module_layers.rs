//! The modules of each folder import one way: no two modules of a folder reach each other,
//! directly or round a circle. Cargo enforces the layers between crates; this test keeps the
//! order inside them, by reading every crate's source for `crate::…` and `super::…` paths
//! (comments and `mod tests` left out) and looking for circles among each folder's modules.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// The crates' source folders, relative to the workspace root.
const CRATE_SOURCES: [&str; 7] = [
    "files/src",
    "loops/src",
    "devices/src",
    "core/src",
    "import/src",
    "engine/src",
    "src",
];

type ModulePath = Vec<String>;

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// `a/b/c.rs` → `[a, b, c]`; `a/mod.rs`, `lib.rs` and `main.rs` name their folder.
fn module_of(root: &Path, file: &Path) -> ModulePath {
    let rel = file.strip_prefix(root).unwrap().with_extension("");
    let mut parts: ModulePath = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if matches!(
        parts.last().map(String::as_str),
        Some("mod" | "lib" | "main")
    ) {
        parts.pop();
    }
    parts
}

/// The code of a file: without its `#[cfg(test)] mod tests` and without comment lines.
fn code_of(text: &str) -> String {
    let mut end = text.len();
    let mut from = 0;
    while let Some(at) = text[from..].find("#[cfg(test)]") {
        let at = from + at;
        let rest = text[at + "#[cfg(test)]".len()..].trim_start();
        if rest.starts_with("mod tests") {
            end = at;
            break;
        }
        from = at + 1;
    }
    text[..end]
        .lines()
        .filter(|l| !l.trim_start().starts_with("//"))
        .collect::<Vec<_>>()
        .join("\n")
}

fn is_ident(c: char) -> bool {
    c.is_ascii_alphanumeric() || c == '_'
}

/// The identifiers of a path starting at `text` (`a::b::C`), stopping at anything else.
fn path_at(text: &str) -> Vec<String> {
    let mut parts = Vec::new();
    let mut rest = text;
    loop {
        let len = rest.find(|c: char| !is_ident(c)).unwrap_or(rest.len());
        if len == 0 {
            break;
        }
        parts.push(rest[..len].to_owned());
        rest = &rest[len..];
        match rest.strip_prefix("::") {
            Some(r) if r.starts_with(is_ident) => rest = r,
            _ => break,
        }
    }
    parts
}

/// Every path the code names from `crate::` or `super::` (each item of a `{…}` group),
/// resolved to a path from the crate root.
fn named_paths(module: &ModulePath, code: &str) -> Vec<ModulePath> {
    let mut found = Vec::new();
    for (at, _) in code.match_indices("::") {
        // The word before `::` must be `crate` or a run of `super`s starting a path.
        let before = &code[..at];
        let word_start = before.rfind(|c: char| !is_ident(c)).map_or(0, |i| i + 1);
        let word = &before[word_start..];
        if word != "crate" && word != "super" {
            continue;
        }
        let prev = before[..word_start].chars().last();
        if prev == Some(':') {
            continue; // inside a longer path (super::super::…): taken from its start
        }
        let mut base: ModulePath = if word == "crate" {
            Vec::new()
        } else {
            module[..module.len().saturating_sub(1)].to_vec()
        };
        let mut rest = &code[at + 2..];
        while let Some(r) = rest.strip_prefix("super::") {
            base.pop();
            rest = r;
        }
        if let Some(group) = rest.strip_prefix('{') {
            let mut depth = 0usize;
            let mut item_start = 0;
            for (i, c) in group.char_indices() {
                match c {
                    '{' => depth += 1,
                    '}' if depth == 0 => {
                        push_item(&mut found, &base, &group[item_start..i]);
                        break;
                    }
                    '}' => depth -= 1,
                    ',' if depth == 0 => {
                        push_item(&mut found, &base, &group[item_start..i]);
                        item_start = i + 1;
                    }
                    _ => {}
                }
            }
        } else {
            push_item(&mut found, &base, rest);
        }
    }
    found
}

fn push_item(found: &mut Vec<ModulePath>, base: &ModulePath, item: &str) {
    let path = path_at(item.trim_start());
    if !path.is_empty() {
        let mut full = base.clone();
        full.extend(path);
        found.push(full);
    }
}

/// The circles among each folder's modules of one crate: (folder, the modules of one circle).
fn circles_in(root: &Path) -> Vec<(String, Vec<String>)> {
    let mut files = Vec::new();
    rust_files(root, &mut files);
    let modules: BTreeMap<ModulePath, PathBuf> = files
        .iter()
        .map(|f| (module_of(root, f), f.clone()))
        .collect();
    // Module → the modules it names (longest known prefix of each path).
    let mut uses: BTreeMap<&ModulePath, BTreeSet<&ModulePath>> = BTreeMap::new();
    for (module, file) in &modules {
        let code = code_of(&std::fs::read_to_string(file).unwrap());
        for path in named_paths(module, &code) {
            let target = (1..=path.len())
                .rev()
                .find_map(|n| modules.get_key_value(&path[..n]).map(|(k, _)| k));
            if let Some(target) = target
                && target != module
            {
                uses.entry(module).or_default().insert(target);
            }
        }
    }
    let folders: BTreeSet<&[String]> = modules
        .keys()
        .filter(|m| !m.is_empty())
        .map(|m| &m[..m.len() - 1])
        .collect();
    let mut circles = Vec::new();
    for folder in folders {
        // The folder's child modules, and which reach which (through anything inside them).
        let child = |m: &ModulePath| -> Option<String> {
            (m.len() > folder.len() && m[..folder.len()] == *folder)
                .then(|| m[folder.len()].clone())
        };
        let mut edges: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
        for (from, targets) in &uses {
            let Some(a) = child(from) else { continue };
            for to in targets {
                if let Some(b) = child(to)
                    && a != b
                {
                    edges.entry(a.clone()).or_default().insert(b);
                }
            }
        }
        for circle in strongly_connected(&edges) {
            if circle.len() > 1 {
                circles.push((folder.join("/"), circle));
            }
        }
    }
    circles
}

/// The strongly connected components of a small graph: each node with every node that both
/// reaches it and is reached from it.
fn strongly_connected(edges: &BTreeMap<String, BTreeSet<String>>) -> Vec<Vec<String>> {
    let reach = |start: &String| -> BTreeSet<String> {
        let mut seen = BTreeSet::new();
        let mut stack = vec![start.clone()];
        while let Some(n) = stack.pop() {
            for m in edges.get(&n).into_iter().flatten() {
                if seen.insert(m.clone()) {
                    stack.push(m.clone());
                }
            }
        }
        seen
    };
    let reached: BTreeMap<&String, BTreeSet<String>> =
        edges.keys().map(|n| (n, reach(n))).collect();
    let mut done = BTreeSet::new();
    let mut components = Vec::new();
    for (n, from_n) in &reached {
        if done.contains(*n) {
            continue;
        }
        let mut component: Vec<String> = from_n
            .iter()
            .filter(|m| reached.get(m).is_some_and(|r| r.contains(*n)))
            .cloned()
            .collect();
        if !component.contains(n) {
            component.push((*n).clone());
        }
        component.sort();
        done.extend(component.iter().cloned());
        components.push(component);
    }
    components
}

#[test]
fn no_module_of_a_folder_reaches_back_to_itself() {
    let workspace = Path::new(env!("CARGO_MANIFEST_DIR"));
    let mut found = Vec::new();
    for source in CRATE_SOURCES {
        for (folder, circle) in circles_in(&workspace.join(source)) {
            found.push(format!("{source}/{folder}: {}", circle.join(" ↔ ")));
        }
    }
    assert!(
        found.is_empty(),
        "modules that import each other:\n{}",
        found.join("\n")
    );
}

#[test]
fn the_reader_finds_a_circle_and_its_folder() {
    let dir = tempfile::tempdir().unwrap();
    let write = |name: &str, text: &str| {
        let path = dir.path().join(name);
        std::fs::create_dir_all(path.parent().unwrap()).unwrap();
        std::fs::write(path, text).unwrap();
    };
    write("lib.rs", "mod a;\nmod b;\nmod c;\nmod inner;\n");
    write("a.rs", "use crate::b::Thing;\n");
    // A group, and a path spelled from the folder above.
    write("b.rs", "use super::{c::Other, a::Item};\n");
    write(
        "c.rs",
        "// use crate::a::Item; (a comment: not an import)\n",
    );
    write("inner/mod.rs", "mod x;\nmod y;\n");
    write("inner/x.rs", "pub fn f() { super::y::g() }\n");
    write(
        "inner/y.rs",
        "pub fn g() {}\n#[cfg(test)]\nmod tests {\n    use crate::inner::x::f;\n}\n",
    );
    let circles = circles_in(dir.path());
    assert_eq!(circles, vec![(String::new(), vec!["a".into(), "b".into()])]);

    // Now y reaches x outside its tests: a second circle, inside `inner`.
    write("inner/y.rs", "pub fn g() { crate::inner::x::f() }\n");
    let circles = circles_in(dir.path());
    assert!(circles.contains(&("inner".into(), vec!["x".into(), "y".into()])));
}
