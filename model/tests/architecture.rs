//! The module structure ARCHITECTURE.md promises, checked on the source text.
//!
//! `model/src` (and `fmu/src`, without the rows) is layered: every top-level module (a file `src/x.rs` or a folder
//! `src/x/`) may use the modules below it and none above, so the import graph between
//! top-level modules has no circle. The test reads each file, drops comments, string
//! literals and `#[cfg(test)]` items (a unit test may drive the whole bench), collects
//! every `crate::` and `super::` path and the names the crate root re-exports, and
//! looks for a circle in the graph.

use std::collections::{BTreeMap, BTreeSet};
use std::fs;
use std::path::{Path, PathBuf};

type Graph = BTreeMap<String, BTreeSet<String>>;

/// Every `.rs` file below `dir`, sorted.
fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for path in entries {
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|x| x == "rs") {
            out.push(path);
        }
    }
}

/// The source with comments removed and string and character literals emptied, so that
/// neither a comment nor a message mentioning `crate::x` counts as a use.
fn code_only(src: &str) -> String {
    let c: Vec<char> = src.chars().collect();
    let mut out = String::with_capacity(src.len());
    let mut i = 0;
    while i < c.len() {
        let next = c.get(i + 1).copied();
        if c[i] == '/' && next == Some('/') {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if c[i] == '/' && next == Some('*') {
            let mut depth = 0;
            while i < c.len() {
                if c[i] == '/' && c.get(i + 1) == Some(&'*') {
                    depth += 1;
                    i += 2;
                } else if c[i] == '*' && c.get(i + 1) == Some(&'/') {
                    depth -= 1;
                    i += 2;
                    if depth == 0 {
                        break;
                    }
                } else {
                    i += 1;
                }
            }
        } else if c[i] == 'r' && matches!(next, Some('#') | Some('"')) && !ident_before(&c, i) {
            // raw string r"..." or r#"..."#
            let mut hashes = 0;
            let mut j = i + 1;
            while c.get(j) == Some(&'#') {
                hashes += 1;
                j += 1;
            }
            if c.get(j) != Some(&'"') {
                out.push(c[i]);
                i += 1;
                continue;
            }
            j += 1;
            loop {
                if j >= c.len() {
                    break;
                }
                if c[j] == '"' && (0..hashes).all(|k| c.get(j + 1 + k) == Some(&'#')) {
                    j += 1 + hashes;
                    break;
                }
                j += 1;
            }
            out.push_str("\"\"");
            i = j;
        } else if c[i] == '"' {
            i += 1;
            while i < c.len() && c[i] != '"' {
                i += if c[i] == '\\' { 2 } else { 1 };
            }
            i += 1;
            out.push_str("\"\"");
        } else if c[i] == '\'' {
            // a character literal ('x', '\n', '\u{..}'), else a lifetime
            let end = if next == Some('\\') {
                (i + 2..c.len()).find(|&j| c[j] == '\'')
            } else if c.get(i + 2) == Some(&'\'') {
                Some(i + 2)
            } else {
                None
            };
            match end {
                Some(e) => {
                    out.push_str("' '");
                    i = e + 1;
                }
                None => {
                    out.push('\'');
                    i += 1;
                }
            }
        } else {
            out.push(c[i]);
            i += 1;
        }
    }
    out
}

fn ident_before(c: &[char], i: usize) -> bool {
    i > 0 && (c[i - 1].is_alphanumeric() || c[i - 1] == '_')
}

/// Index just past the item starting at `i`: to its `;` or past its balanced `{...}`.
fn item_end(code: &[u8], mut i: usize) -> usize {
    while i < code.len() {
        match code[i] {
            b';' => return i + 1,
            b'{' => {
                let mut depth = 0;
                while i < code.len() {
                    match code[i] {
                        b'{' => depth += 1,
                        b'}' => {
                            depth -= 1;
                            if depth == 0 {
                                return i + 1;
                            }
                        }
                        _ => {}
                    }
                    i += 1;
                }
            }
            _ => i += 1,
        }
    }
    code.len()
}

/// `code` without its `#[cfg(test)]` items, and the names of the test modules it
/// declares out of line (`#[cfg(test)] mod tests;`).
fn without_tests(code: &str) -> (String, Vec<String>) {
    const MARK: &str = "#[cfg(test)]";
    let bytes = code.as_bytes();
    let mut out = String::new();
    let mut test_files = Vec::new();
    let mut from = 0;
    while let Some(at) = code[from..].find(MARK).map(|k| from + k) {
        out.push_str(&code[from..at]);
        let start = at + MARK.len();
        let end = item_end(bytes, start);
        let item: Vec<&str> = code[start..end].split_whitespace().collect();
        if let Some(k) = item.iter().position(|w| *w == "mod") {
            if let Some(name) = item.get(k + 1).and_then(|n| n.strip_suffix(';')) {
                test_files.push(name.to_string());
            }
        }
        from = end;
    }
    out.push_str(&code[from..]);
    (out, test_files)
}

fn ident_at(s: &str) -> Option<&str> {
    let end = s
        .find(|ch: char| !(ch.is_alphanumeric() || ch == '_'))
        .unwrap_or(s.len());
    (end > 0).then(|| &s[..end])
}

/// First path segment of every path that follows `prefix` (`prefix::a::..`, or each
/// element of `prefix::{a::.., b, ..}`).
fn segments_after(code: &str, prefix: &str) -> Vec<String> {
    let mut found = Vec::new();
    let bytes = code.as_bytes();
    let mut from = 0;
    while let Some(at) = code[from..].find(prefix).map(|k| from + k) {
        from = at + prefix.len();
        let is_start = at == 0 || {
            let b = bytes[at - 1];
            !(b.is_ascii_alphanumeric() || b == b'_' || b == b':')
        };
        if !is_start {
            continue;
        }
        let rest = code[from..].trim_start();
        if let Some(group) = rest.strip_prefix('{') {
            let mut depth = 1;
            let mut element_start = true;
            for (k, ch) in group.char_indices() {
                match ch {
                    '{' => depth += 1,
                    '}' => {
                        depth -= 1;
                        if depth == 0 {
                            break;
                        }
                    }
                    ',' if depth == 1 => element_start = true,
                    ch if ch.is_whitespace() => {}
                    _ if element_start && depth == 1 => {
                        element_start = false;
                        if let Some(name) = ident_at(&group[k..]) {
                            found.push(name.to_string());
                        }
                    }
                    _ => {}
                }
            }
        } else if let Some(name) = ident_at(rest) {
            found.push(name.to_string());
        }
    }
    found
}

/// Names the crate root re-exports (`pub use bench::{Bench, ..}`) and the module each
/// comes from, so that `crate::Bench` counts as a use of `bench`.
fn root_reexports(lib: &str) -> BTreeMap<String, String> {
    let mut map = BTreeMap::new();
    for stmt in lib.split(';') {
        let Some(rest) = stmt.trim().strip_prefix("pub use ") else {
            continue;
        };
        let rest = rest.trim().trim_start_matches("crate::");
        let Some((module, names)) = rest.split_once("::") else {
            continue;
        };
        let names = names.trim().trim_start_matches('{').trim_end_matches('}');
        for name in names.split(',') {
            let name = name.trim();
            let name = name.rsplit(" as ").next().unwrap_or(name).trim();
            if !name.is_empty() {
                map.insert(name.to_string(), module.trim().to_string());
            }
        }
    }
    map
}

/// The import graph between the top-level modules of the crate whose sources are in `src`.
fn module_graph(src: &Path) -> Graph {
    let mut files = Vec::new();
    rust_files(src, &mut files);
    let lib = code_only(&fs::read_to_string(src.join("lib.rs")).expect("lib.rs"));
    let reexports = root_reexports(&lib);
    let mut modules = BTreeSet::new();
    for f in &files {
        let rel = f.strip_prefix(src).unwrap();
        let top = rel
            .components()
            .next()
            .unwrap()
            .as_os_str()
            .to_string_lossy();
        let top = top.trim_end_matches(".rs").to_string();
        if top != "lib" {
            modules.insert(top);
        }
    }
    // out-of-line test modules, found in their parents
    let mut test_files = BTreeSet::new();
    let mut code_of = BTreeMap::new();
    for f in &files {
        let (code, tests) = without_tests(&code_only(&fs::read_to_string(f).unwrap()));
        // where the file's own submodules live: src/a/mod.rs -> src/a, src/a/b.rs -> src/a/b
        let dir = if f.file_name().unwrap() == "mod.rs" {
            f.parent().unwrap().to_path_buf()
        } else {
            f.with_extension("")
        };
        for t in tests {
            // the module's file, or its folder and everything in it
            test_files.insert(dir.join(format!("{t}.rs")));
            test_files.insert(dir.join(&t));
        }
        code_of.insert(f.clone(), code);
    }
    let mut graph: Graph = modules
        .iter()
        .map(|m| (m.clone(), BTreeSet::new()))
        .collect();
    for (f, code) in &code_of {
        let rel = f.strip_prefix(src).unwrap();
        let parts: Vec<String> = rel
            .components()
            .map(|c| {
                c.as_os_str()
                    .to_string_lossy()
                    .trim_end_matches(".rs")
                    .to_string()
            })
            .collect();
        let top = parts[0].clone();
        let in_tests = |t: &PathBuf| f.starts_with(t);
        if top == "lib" || test_files.iter().any(in_tests) {
            continue;
        }
        // module path of the file: src/a/b.rs is a::b, src/a/mod.rs is a
        let depth = parts.len() - usize::from(parts.last().is_some_and(|p| p == "mod"));
        let mut used: Vec<String> = segments_after(code, "crate::");
        // from a::b, super::super::x is the root's x
        used.extend(segments_after(code, &"super::".repeat(depth)));
        for name in used {
            let target = reexports.get(&name).cloned().unwrap_or(name);
            if modules.contains(&target) && target != top {
                graph.get_mut(&top).unwrap().insert(target);
            }
        }
    }
    graph
}

/// A circle of the graph, as the list of modules along it (first = last), if any.
fn find_cycle(graph: &Graph) -> Option<Vec<String>> {
    fn visit(
        node: &str,
        graph: &Graph,
        state: &mut BTreeMap<String, u8>,
        stack: &mut Vec<String>,
    ) -> Option<Vec<String>> {
        state.insert(node.to_string(), 1);
        stack.push(node.to_string());
        for next in graph.get(node).into_iter().flatten() {
            match state.get(next.as_str()).copied().unwrap_or(0) {
                1 => {
                    let start = stack.iter().position(|n| n == next).unwrap();
                    let mut cycle = stack[start..].to_vec();
                    cycle.push(next.clone());
                    return Some(cycle);
                }
                0 => {
                    if let Some(c) = visit(next, graph, state, stack) {
                        return Some(c);
                    }
                }
                _ => {}
            }
        }
        stack.pop();
        state.insert(node.to_string(), 2);
        None
    }
    let mut state = BTreeMap::new();
    for node in graph.keys() {
        if state.get(node.as_str()).copied().unwrap_or(0) == 0 {
            let mut stack = Vec::new();
            if let Some(c) = visit(node, graph, &mut state, &mut stack) {
                return Some(c);
            }
        }
    }
    None
}

fn describe(graph: &Graph) -> String {
    graph
        .iter()
        .map(|(m, uses)| {
            format!(
                "  {m} -> {}",
                uses.iter().cloned().collect::<Vec<_>>().join(", ")
            )
        })
        .collect::<Vec<_>>()
        .join("\n")
}

fn model_src() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("src")
}

#[test]
fn model_modules_import_each_other_without_a_circle() {
    let graph = model_graph_checked();
    if let Some(cycle) = find_cycle(&graph) {
        panic!(
            "import circle between model/src modules: {}\nwhole graph:\n{}",
            cycle.join(" -> "),
            describe(&graph)
        );
    }
    println!("model/src module graph:\n{}", describe(&graph));
}

#[test]
fn fmu_modules_import_each_other_without_a_circle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("../fmu/src");
    let graph = module_graph(&src);
    for (from, to) in [("models", "slave"), ("instance", "slave"), ("slave", "ffi")] {
        assert!(
            graph[from].contains(to),
            "the reader missed {from} -> {to}:\n{}",
            describe(&graph)
        );
    }
    if let Some(cycle) = find_cycle(&graph) {
        panic!(
            "import circle between fmu/src modules: {}\nwhole graph:\n{}",
            cycle.join(" -> "),
            describe(&graph)
        );
    }
}

/// The graph of model/src, with a check that the reader sees the uses it must see (a
/// reader that found nothing would find no circle either).
fn model_graph_checked() -> Graph {
    let graph = module_graph(&model_src());
    for (from, to) in [
        ("bench", "solver"),
        ("bench", "servovalve"),
        ("control", "bench"),
    ] {
        assert!(
            graph[from].contains(to),
            "the reader missed {from} -> {to}:\n{}",
            describe(&graph)
        );
    }
    graph
}

#[test]
fn the_reader_sees_grouped_super_and_reexported_paths_and_not_comments() {
    let dir = std::env::temp_dir().join(format!("hb-arch-{}", std::process::id()));
    let _ = fs::remove_dir_all(&dir);
    fs::create_dir_all(dir.join("a")).unwrap();
    let write = |p: &str, s: &str| fs::write(dir.join(p), s).unwrap();
    write(
        "lib.rs",
        "pub mod a;\npub mod b;\npub mod c;\npub mod d;\npub use d::{Thing, Other as O};\n",
    );
    // a -> b (grouped), a -> d (through a root re-export); not a -> c (comment, string)
    write(
        "a/mod.rs",
        "mod inner;\n#[cfg(test)]\nmod tests;\nuse crate::{b::X, Thing};\n// crate::c::Y\nconst S: &str = \"crate::c\";\nfn f<'a>(x: &'a str) -> char { 'c' }\n",
    );
    // a::inner -> c through super::super
    write("a/inner.rs", "use super::super::c::Z;\n");
    // test code does not count: no a -> b -> a circle from here
    write("a/tests.rs", "use crate::b::X;\n");
    write(
        "b.rs",
        "pub struct X;\n#[cfg(test)]\nmod tests { use crate::a; }\n",
    );
    write(
        "c.rs",
        "/* crate::a:: */ pub struct Z;\n#[cfg(test)]\nmod checks;\n",
    );
    // nor does a test module kept in a folder of its own
    fs::create_dir_all(dir.join("c/checks")).unwrap();
    write("c/checks/mod.rs", "mod helpers;\nuse crate::a;\n");
    write("c/checks/helpers.rs", "use crate::b;\n");
    write("d.rs", "pub struct Thing; pub struct Other;\n");
    let graph = module_graph(&dir);
    let edges = |m: &str| graph[m].iter().cloned().collect::<Vec<_>>();
    assert_eq!(edges("a"), ["b", "c", "d"], "{}", describe(&graph));
    assert!(
        edges("b").is_empty() && edges("c").is_empty(),
        "{}",
        describe(&graph)
    );
    assert_eq!(find_cycle(&graph), None);
    // and a circle, once there, is found and named
    write("d.rs", "use crate::a::X;\n");
    let graph = module_graph(&dir);
    assert_eq!(
        find_cycle(&graph).expect("a -> d -> a"),
        ["a", "d", "a"],
        "{}",
        describe(&graph)
    );
    fs::remove_dir_all(&dir).unwrap();
}

/// The rows of the diagram in ARCHITECTURE.md, lowest first: a module imports only
/// modules of lower rows.
const LAYERS: &[&[&str]] = &[
    &[
        "effects", "fluid", "friction", "jacobian", "sensors", "solver",
    ],
    &["params"],
    &["servovalve", "manifold", "actuator"],
    &["component"],
    &["bench"],
    &["control"],
];

#[test]
fn model_modules_import_only_lower_rows_of_the_architecture_diagram() {
    let graph = model_graph_checked();
    let row = |m: &str| LAYERS.iter().position(|r| r.contains(&m));
    let mut wrong = Vec::new();
    for (from, uses) in &graph {
        let Some(r) = row(from) else {
            wrong.push(format!(
                "{from} is in no row: add it to LAYERS and ARCHITECTURE.md"
            ));
            continue;
        };
        for to in uses {
            if row(to).is_none_or(|t| t >= r) {
                wrong.push(format!("{from} (row {r}) imports {to} (row {:?})", row(to)));
            }
        }
    }
    assert!(
        wrong.is_empty(),
        "{}\nwhole graph:\n{}",
        wrong.join("\n"),
        describe(&graph)
    );
}

/// Longest a Rust file of the workspace may be: the guide's "no file much over 600 lines".
const MAX_LINES: usize = 650;

/// Every `.rs` file of the workspace that is not build output or a hidden folder
/// (`target/`, `.git/`, `.venv/`).
fn workspace_rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    let mut entries: Vec<_> = fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("cannot read {}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .collect();
    entries.sort();
    for path in entries {
        let name = path.file_name().unwrap().to_string_lossy();
        if path.is_dir() {
            if !(name.starts_with('.') || name == "target") {
                workspace_rust_files(&path, out);
            }
        } else if name.ends_with(".rs") {
            out.push(path);
        }
    }
}

#[test]
fn no_rust_file_of_the_workspace_is_much_over_600_lines() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR")).parent().unwrap();
    let mut files = Vec::new();
    workspace_rust_files(root, &mut files);
    let sources: Vec<_> = files
        .iter()
        .filter(|f| f.starts_with(root.join("model").join("src")))
        .collect();
    assert!(
        files.len() > 50 && !sources.is_empty(),
        "found only {} files under {}",
        files.len(),
        root.display()
    );
    let mut long: Vec<(usize, String)> = files
        .iter()
        .map(|f| {
            let text = fs::read_to_string(f).unwrap_or_default();
            let rel = f.strip_prefix(root).unwrap().display().to_string();
            (text.lines().count(), rel)
        })
        .filter(|(n, _)| *n > MAX_LINES)
        .collect();
    long.sort();
    assert!(
        long.is_empty(),
        "files over {MAX_LINES} lines (split them by what they hold):\n{}",
        long.iter()
            .map(|(n, f)| format!("  {n:5} {f}"))
            .collect::<Vec<_>>()
            .join("\n")
    );
}
