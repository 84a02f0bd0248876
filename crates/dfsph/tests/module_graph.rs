//! The module graph of every crate in the workspace has no cycle (issue 49, item 4).
//!
//! A module A depends on a module B when A's code names an item through B: a `use` of it or a
//! path from `crate::`, `super::`, `self::` or a child's name. A re-export (`pub use`) is an
//! edge of the module that makes it, and naming an item through it is an edge to that module,
//! except for the crate root's re-exports, the crate's public face, which count as the
//! module they name. Declaring a child (`mod b;`) is not an edge, and nothing under
//! `#[cfg(test)]` counts: tests may reach anywhere. Doc comments and strings are not read.
//!
//! With no cycle every module can be read, tested and replaced from the bottom up: the
//! kernels under the neighbour search under the solves under the simulation under the
//! actions, recording and probes. A cycle makes a group of files one unit whatever their
//! names say. The test prints each cycle it finds, file by file with the names that tie them.

use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};

/// A module path inside one crate: the names from the crate root (`[]` for lib.rs/main.rs).
type ModPath = Vec<String>;

/// The paths a module names, each with whether it is a re-export (`pub use`).
type NamedPaths = Vec<(Vec<String>, bool)>;

/// One crate's modules: path → source (comments, strings and test code removed).
struct Crate {
    name: String,
    modules: BTreeMap<ModPath, String>,
}

/// The workspace's root, from the manifest directory of this crate (crates/dfsph).
fn workspace_root() -> PathBuf {
    let manifest = std::env::var("CARGO_MANIFEST_DIR")
        .unwrap_or_else(|_| env!("CARGO_MANIFEST_DIR").to_string());
    Path::new(&manifest)
        .ancestors()
        .nth(2)
        .expect("crates/dfsph lies two levels under the workspace root")
        .to_path_buf()
}

/// Remove comments and the contents of string and character literals, keeping the code.
fn strip(source: &str) -> String {
    let chars: Vec<char> = source.chars().collect();
    let mut out = String::with_capacity(source.len());
    let mut i = 0;
    while i < chars.len() {
        let c = chars[i];
        let next = chars.get(i + 1).copied();
        if c == '/' && next == Some('/') {
            while i < chars.len() && chars[i] != '\n' {
                i += 1;
            }
        } else if c == '/' && next == Some('*') {
            let mut depth = 0;
            while i < chars.len() {
                if chars[i] == '/' && chars.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if chars[i] == '*' && chars.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
            out.push(' ');
        } else if c == 'r' && (next == Some('"') || next == Some('#')) && !ident_before(&chars, i) {
            // A raw string: r"…" or r#"…"#.
            let mut j = i + 1;
            let mut hashes = 0;
            while chars.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if chars.get(j) != Some(&'"') {
                out.push(c);
                i += 1;
                continue;
            }
            j += 1;
            loop {
                if j >= chars.len() {
                    break;
                }
                if chars[j] == '"' && (0..hashes).all(|k| chars.get(j + 1 + k) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            out.push_str("\"\"");
            i = j;
        } else if c == '"' {
            i += 1;
            while i < chars.len() && chars[i] != '"' {
                if chars[i] == '\\' {
                    i += 1;
                }
                i += 1;
            }
            i += 1;
            out.push_str("\"\"");
        } else if c == '\'' {
            // A character literal ('x', '\n', '\u{..}') or a lifetime ('a).
            let close = if next == Some('\\') {
                (i + 2..chars.len().min(i + 12)).find(|&j| chars[j] == '\'')
            } else if chars.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            match close {
                Some(j) => {
                    out.push_str("' '");
                    i = j + 1;
                }
                None => {
                    out.push(c);
                    i += 1;
                }
            }
        } else {
            out.push(c);
            i += 1;
        }
    }
    out
}

/// The next `#[cfg(…)]` whose condition names `test` (`test`, `all(test, …)`), as its start
/// and end.
fn next_test_attribute(code: &str) -> Option<(usize, usize)> {
    let mut k = 0;
    while let Some(at) = code[k..].find("#[cfg(") {
        let start = k + at;
        let end = start + code[start..].find(")]")? + 2;
        let condition = &code[start..end];
        let names_test = condition
            .split(|c: char| !(c.is_alphanumeric() || c == '_'))
            .any(|w| w == "test");
        if names_test && !condition.contains("not(test") {
            return Some((start, end));
        }
        k = end;
    }
    None
}

fn ident_before(chars: &[char], i: usize) -> bool {
    i > 0 && (chars[i - 1].is_alphanumeric() || chars[i - 1] == '_')
}

/// Remove every item under `#[cfg(test)]` (a `mod tests { … }`, a test helper), and return
/// the names of child modules declared there (`#[cfg(test)] mod tests;`), whose files are
/// test code as well.
fn strip_test_code(code: &str) -> (String, Vec<String>) {
    let mut out = String::with_capacity(code.len());
    let mut test_children = Vec::new();
    let mut rest = code;
    while let Some((at, attribute_end)) = next_test_attribute(rest) {
        out.push_str(&rest[..at]);
        let item = &rest[attribute_end..];
        // The item ends at its first `;` outside braces, or at the brace closing its first
        // `{`.
        let mut depth = 0usize;
        let mut end = item.len();
        for (k, ch) in item.char_indices() {
            match ch {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = k + 1;
                        break;
                    }
                }
                ';' if depth == 0 => {
                    end = k + 1;
                    break;
                }
                _ => {}
            }
        }
        let declaration = item[..end].trim();
        if let Some(name) = declaration
            .strip_prefix("mod ")
            .or_else(|| declaration.strip_prefix("pub mod "))
            .and_then(|s| s.strip_suffix(';'))
        {
            test_children.push(name.trim().to_string());
        }
        rest = &item[end..];
    }
    out.push_str(rest);
    (out, test_children)
}

/// Read one crate: its root file and every module file under src/.
fn read_crate(name: &str, src: &Path) -> Crate {
    let mut modules = BTreeMap::new();
    let mut test_files = BTreeSet::new();
    let mut files = Vec::new();
    collect_rs(src, &mut files);
    for file in &files {
        let rel = file.strip_prefix(src).unwrap();
        let mut parts: Vec<String> = rel
            .iter()
            .map(|p| p.to_string_lossy().into_owned())
            .collect();
        let last = parts.pop().unwrap();
        let stem = last.trim_end_matches(".rs").to_string();
        let path: ModPath = match stem.as_str() {
            "lib" | "main" if parts.is_empty() => Vec::new(),
            "mod" => parts.clone(),
            _ => {
                parts.push(stem);
                parts
            }
        };
        let source = std::fs::read_to_string(file).unwrap();
        let (code, test_children) = strip_test_code(&strip(&source));
        for child in test_children {
            let mut p = path.clone();
            p.push(child);
            test_files.insert(p);
        }
        modules.insert(path, code);
    }
    for p in test_files {
        modules.remove(&p);
    }
    Crate {
        name: name.to_string(),
        modules,
    }
}

fn collect_rs(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            collect_rs(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// Expand one `use` tree (`a::{b, c::{d, e as f}}`) into its paths; `self` in a group names
/// the group's prefix.
fn expand_use_tree(tree: &str) -> Vec<Vec<String>> {
    // Drop renames (`e as f`, `_ as _`): the path is what it names.
    let spaced = tree
        .replace('{', " { ")
        .replace('}', " } ")
        .replace(',', " , ");
    let mut words = Vec::new();
    let mut it = spaced.split_whitespace();
    while let Some(word) = it.next() {
        if word == "as" {
            it.next();
        } else {
            words.push(word);
        }
    }
    let tree = words.concat();
    let mut out = Vec::new();
    expand_into(&tree, &mut Vec::new(), &mut out);
    out
}

fn expand_into(tree: &str, prefix: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
    let depth = prefix.len();
    match tree.find('{') {
        Some(open) => {
            prefix.extend(segments(&tree[..open]));
            let inner = &tree[open + 1..tree.rfind('}').unwrap_or(tree.len())];
            for part in split_top_level(inner) {
                if part == "self" {
                    out.push(prefix.clone());
                } else if !part.is_empty() {
                    expand_into(&part, prefix, out);
                }
            }
        }
        None => {
            prefix.extend(segments(tree));
            out.push(prefix.clone());
        }
    }
    prefix.truncate(depth);
}

fn segments(path: &str) -> impl Iterator<Item = String> + '_ {
    path.split("::")
        .filter(|s| !s.is_empty())
        .map(str::to_string)
}

/// Split a group's contents at its top-level commas.
fn split_top_level(s: &str) -> Vec<String> {
    let (mut parts, mut depth, mut start) = (Vec::new(), 0, 0);
    for (k, ch) in s.char_indices() {
        match ch {
            '{' => depth += 1,
            '}' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(s[start..k].to_string());
                start = k + 1;
            }
            _ => {}
        }
    }
    parts.push(s[start..].to_string());
    parts
}

/// For every byte of `code`, how many inline modules (`mod name { … }`) enclose it.
fn inline_depths(code: &str) -> Vec<u8> {
    let mut depths = vec![0u8; code.len() + 1];
    let mut stack: Vec<bool> = Vec::new();
    let mut depth = 0u8;
    for (k, ch) in code.char_indices() {
        match ch {
            '{' => {
                let before = code[..k].trim_end();
                let name_start = before
                    .rfind(|c: char| !(c.is_alphanumeric() || c == '_'))
                    .map_or(0, |p| p + 1);
                let is_mod =
                    before[..name_start].trim_end().ends_with("mod") && name_start < before.len();
                stack.push(is_mod);
                if is_mod {
                    depth += 1;
                }
            }
            '}' => depth -= u8::from(stack.pop() == Some(true)),
            _ => {}
        }
        depths[k] = depth;
    }
    depths
}

/// The paths a module's code names: every `use` tree, and every path written out from
/// `crate::`, `super::` or `self::`, with whether it is a public re-export.
fn named_paths(code: &str, children: &[String]) -> NamedPaths {
    let depths = inline_depths(code);
    // Inside an inline module the first `super`s climb to the file's own module.
    let from_file = |start: usize, mut path: Vec<String>| {
        for _ in 0..depths[start] {
            match path.first().map(String::as_str) {
                Some("super") => {
                    path[0] = "self".to_string();
                }
                _ => break,
            }
            if path.len() > 1 && path[1] == "super" {
                path.remove(0);
            }
        }
        path
    };
    let mut out = Vec::new();
    // `use` declarations, public or not.
    let bytes = code.as_bytes();
    let mut k = 0;
    while let Some(at) = code[k..].find("use ") {
        let start = k + at;
        k = start + 4;
        if start > 0 && (bytes[start - 1].is_ascii_alphanumeric() || bytes[start - 1] == b'_') {
            continue;
        }
        let before = code[..start].trim_end();
        let public = ["pub", "pub(crate)", "pub(super)"]
            .iter()
            .any(|p| before.ends_with(p));
        let Some(end) = code[start..].find(';') else {
            break;
        };
        let tree = &code[start + 4..start + end];
        for path in expand_use_tree(tree) {
            out.push((from_file(start, path), public));
        }
        k = start + end;
    }
    // Paths written out in the code, from the crate, a parent, this module or a child
    // (`jacobi::Jacobi::default()`).
    let roots = ["crate", "super", "self"]
        .into_iter()
        .chain(children.iter().map(String::as_str))
        .map(|r| format!("{r}::"));
    for root in roots {
        let root = root.as_str();
        let mut k = 0;
        while let Some(at) = code[k..].find(root) {
            let start = k + at;
            k = start + root.len();
            let after_path = start >= 2 && &code[start - 2..start] == "::";
            if after_path
                || start > 0
                    && (bytes[start - 1].is_ascii_alphanumeric() || bytes[start - 1] == b'_')
            {
                continue;
            }
            let end = code[start..]
                .find(|c: char| !(c.is_alphanumeric() || c == '_' || c == ':'))
                .map_or(code.len(), |e| start + e);
            // `super::{a, b}` and `super::*` belong to a `use`, read above.
            if code[end..].starts_with(['{', '*']) {
                continue;
            }
            out.push((
                from_file(start, segments(&code[start..end]).collect()),
                false,
            ));
        }
    }
    out
}

/// The names of a module's child modules that have files of their own.
fn children(krate: &Crate, module: &ModPath) -> Vec<String> {
    krate
        .modules
        .keys()
        .filter(|p| p.len() == module.len() + 1 && p.starts_with(module))
        .map(|p| p[module.len()].clone())
        .collect()
}

/// A path as named in module `from`, made absolute (from the crate root), or None when it
/// leaves the crate (another crate, std).
fn absolute(from: &ModPath, path: &[String], krate: &Crate) -> Option<Vec<String>> {
    let mut base: Vec<String>;
    let mut rest = path;
    match rest.first().map(String::as_str) {
        Some("crate") => {
            base = Vec::new();
            rest = &rest[1..];
        }
        Some("super") | Some("self") => {
            base = from.clone();
            while let Some(first) = rest.first() {
                match first.as_str() {
                    "super" => {
                        base.pop();
                    }
                    "self" => {}
                    _ => break,
                }
                rest = &rest[1..];
            }
        }
        Some(first) => {
            // A path relative to this module: a child module's name (`use child::Item`).
            let mut child = from.clone();
            child.push(first.to_string());
            if krate.modules.contains_key(&child) {
                base = from.clone();
            } else {
                return None;
            }
        }
        None => return None,
    }
    base.extend(rest.iter().cloned());
    Some(base)
}

/// The module an absolute path names: its longest prefix that is a module, followed through
/// the crate root's re-exports (`face`). Only the root's re-exports are seen through: a module
/// that names an item through another module's re-export depends on that module.
fn defining_module(path: &[String], krate: &Crate, face: &RootFace) -> Option<ModPath> {
    let mut path = path.to_vec();
    for _ in 0..16 {
        let module_len = (0..=path.len())
            .rev()
            .find(|&n| krate.modules.contains_key(&path[..n]))?;
        let target = path
            .get(module_len)
            .filter(|_| module_len == 0)
            .and_then(|item| face.get(item));
        match target {
            Some(target) => {
                let mut next = target.clone();
                next.extend(path[module_len + 1..].iter().cloned());
                path = next;
            }
            None => return Some(path[..module_len].to_vec()),
        }
    }
    None
}

/// The crate root's re-exports, its public face: name → the absolute path it re-exports.
type RootFace = BTreeMap<String, Vec<String>>;

/// Every dependency edge of one crate: (from, to) → the names that tie them.
fn edges(krate: &Crate) -> BTreeMap<(ModPath, ModPath), BTreeSet<String>> {
    // Every module's named paths, made absolute, and whether each is a re-export.
    let named: Vec<(&ModPath, NamedPaths)> = krate
        .modules
        .iter()
        .map(|(module, code)| {
            let paths = named_paths(code, &children(krate, module))
                .into_iter()
                .filter_map(|(path, public)| Some((absolute(module, &path, krate)?, public)))
                .collect();
            (module, paths)
        })
        .collect();
    let face: RootFace = named
        .iter()
        .filter(|(module, _)| module.is_empty())
        .flat_map(|(_, paths)| paths.iter().filter(|(_, public)| *public))
        .filter_map(|(abs, _)| Some((abs.last()?.clone(), abs.clone())))
        .collect();
    let mut out: BTreeMap<(ModPath, ModPath), BTreeSet<String>> = BTreeMap::new();
    for (module, paths) in &named {
        for (abs, _) in paths {
            let Some(target) = defining_module(abs, krate, &face) else {
                continue;
            };
            // A module's own items, and its ancestors' mere declarations of it, are not
            // edges; naming a module itself (`use crate::pressure;`) is.
            if &target == *module {
                continue;
            }
            let name = abs.get(target.len()).cloned().unwrap_or_default();
            out.entry(((*module).clone(), target))
                .or_default()
                .insert(name);
        }
    }
    out
}

/// The strongly connected components with more than one module (Tarjan).
fn cycles(
    nodes: &[ModPath],
    edges: &BTreeMap<(ModPath, ModPath), BTreeSet<String>>,
) -> Vec<Vec<ModPath>> {
    let index_of: BTreeMap<&ModPath, usize> =
        nodes.iter().enumerate().map(|(i, n)| (n, i)).collect();
    let mut adjacency = vec![Vec::new(); nodes.len()];
    for (from, to) in edges.keys() {
        if let (Some(&a), Some(&b)) = (index_of.get(from), index_of.get(to)) {
            adjacency[a].push(b);
        }
    }
    struct State {
        index: Vec<Option<usize>>,
        low: Vec<usize>,
        on_stack: Vec<bool>,
        stack: Vec<usize>,
        next: usize,
        out: Vec<Vec<usize>>,
    }
    fn visit(v: usize, adj: &[Vec<usize>], s: &mut State) {
        s.index[v] = Some(s.next);
        s.low[v] = s.next;
        s.next += 1;
        s.stack.push(v);
        s.on_stack[v] = true;
        for &w in &adj[v] {
            match s.index[w] {
                None => {
                    visit(w, adj, s);
                    s.low[v] = s.low[v].min(s.low[w]);
                }
                Some(iw) if s.on_stack[w] => s.low[v] = s.low[v].min(iw),
                _ => {}
            }
        }
        if Some(s.low[v]) == s.index[v] {
            let mut component = Vec::new();
            loop {
                let w = s.stack.pop().unwrap();
                s.on_stack[w] = false;
                component.push(w);
                if w == v {
                    break;
                }
            }
            if component.len() > 1 {
                s.out.push(component);
            }
        }
    }
    let n = nodes.len();
    let mut s = State {
        index: vec![None; n],
        low: vec![0; n],
        on_stack: vec![false; n],
        stack: Vec::new(),
        next: 0,
        out: Vec::new(),
    };
    for v in 0..n {
        if s.index[v].is_none() {
            visit(v, &adjacency, &mut s);
        }
    }
    s.out
        .into_iter()
        .map(|c| {
            let mut c: Vec<ModPath> = c.into_iter().map(|i| nodes[i].clone()).collect();
            c.sort();
            c
        })
        .collect()
}

fn show(krate: &str, module: &ModPath) -> String {
    if module.is_empty() {
        format!("{krate}::(root)")
    } else {
        format!("{krate}::{}", module.join("::"))
    }
}

/// Every crate of the workspace, with its source folder.
fn workspace_crates() -> Vec<Crate> {
    let root = workspace_root();
    let mut out = Vec::new();
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(root.join("crates"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    dirs.push(root.join("python"));
    dirs.sort();
    for dir in dirs {
        let src = dir.join("src");
        if src.is_dir() {
            let name = dir.file_name().unwrap().to_string_lossy().into_owned();
            out.push(read_crate(&name, &src));
        }
    }
    out
}

#[test]
fn no_crate_has_a_cycle_in_its_module_graph() {
    let crates = workspace_crates();
    assert!(
        crates.iter().any(|c| c.name == "dfsph") && crates.len() >= 5,
        "the workspace's crates were not found"
    );
    let mut report = String::new();
    for krate in &crates {
        let edges = edges(krate);
        let nodes: Vec<ModPath> = krate.modules.keys().cloned().collect();
        for cycle in cycles(&nodes, &edges) {
            report.push_str(&format!("a cycle of {} modules:\n", cycle.len()));
            let members: BTreeSet<&ModPath> = cycle.iter().collect();
            for ((from, to), names) in &edges {
                if members.contains(from) && members.contains(to) {
                    let names: Vec<&str> = names.iter().map(String::as_str).collect();
                    report.push_str(&format!(
                        "  {} -> {}: {}\n",
                        show(&krate.name, from),
                        show(&krate.name, to),
                        names.join(", ")
                    ));
                }
            }
        }
    }
    assert!(report.is_empty(), "{report}");
}

#[test]
fn the_checker_finds_a_cycle_and_reads_only_code() {
    let module = |path: &[&str], code: &str| {
        (
            path.iter().map(|s| s.to_string()).collect::<ModPath>(),
            strip_test_code(&strip(code)).0,
        )
    };
    let krate = Crate {
        name: "toy".into(),
        modules: BTreeMap::from([
            module(&[], "mod a; mod b; mod c; pub use c::Thing;"),
            module(
                &["a"],
                "use crate::b::f; use crate::d::Thing; // crate::c::no_edge\n",
            ),
            module(
                &["b"],
                "pub fn f() { crate::Thing::new(); let _ = \"crate::a::g\"; }",
            ),
            module(
                &["c"],
                "pub struct Thing; #[cfg(test)] mod tests { use crate::a::g; }",
            ),
            module(&["d"], "pub use crate::c::Thing;"),
        ]),
    };
    let e = edges(&krate);
    let key = |a: &str, b: &str| (vec![a.to_string()], vec![b.to_string()]);
    assert!(e.contains_key(&key("a", "b")));
    assert!(
        e.contains_key(&key("b", "c")),
        "the re-export leads to c: {e:?}"
    );
    assert!(
        e.contains_key(&key("a", "d")),
        "a facade that is not the root is an edge"
    );
    assert!(e.contains_key(&key("d", "c")), "a re-export is an edge");
    assert!(!e.contains_key(&key("a", "c")), "comments are not read");
    assert!(!e.contains_key(&key("b", "a")), "strings are not read");
    assert!(!e.contains_key(&key("c", "a")), "test code is not read");
    let nodes: Vec<ModPath> = krate.modules.keys().cloned().collect();
    assert!(cycles(&nodes, &e).is_empty());
    let mut cyclic = krate;
    cyclic.modules.insert(
        vec!["c".into()],
        "pub struct Thing; fn g() { super::a::h(); }".into(),
    );
    let e = edges(&cyclic);
    let found = cycles(&nodes, &e);
    assert_eq!(found.len(), 1, "{e:?}");
    assert_eq!(found[0].len(), 4, "a, b, c and d, through c -> a");
}
