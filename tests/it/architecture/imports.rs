//! The files of one crate's `src/` as a graph: an edge from a file to each
//! file whose items it names (`use` paths and qualified paths through
//! `crate::`, `super::`, `self::` or a child module, followed through
//! `pub use` re-exports to the file that defines the item). A re-export
//! itself is no edge (a facade `mod.rs` that only declares and re-exports
//! modules depends on nothing), nor is code in `#[cfg(test)] mod … { }`.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::Path;

type Module = Vec<String>;

/// Module path of a file under `src` (`robot/arm/stance.rs` →
/// `[robot, arm, stance]`; `lib.rs` and `mod.rs` name their folder).
fn module_of(src: &Path, file: &Path) -> Module {
    let rel = file.strip_prefix(src).unwrap().with_extension("");
    let mut parts: Module = rel
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

/// The text without line comments and `#[cfg(test)] mod x { … }` blocks.
fn strip(text: &str) -> String {
    let mut text: String = text
        .lines()
        .map(|l| l.find("//").map_or(l, |i| &l[..i]))
        .collect::<Vec<_>>()
        .join("\n");
    while let Some(start) = text.find("#[cfg(test)]") {
        let rest = &text[start + "#[cfg(test)]".len()..];
        let trimmed = rest.trim_start();
        let is_mod_block = trimmed.starts_with("mod ")
            && trimmed
                .find('{')
                .is_some_and(|b| trimmed.find(';').is_none_or(|s| b < s));
        if !is_mod_block {
            text.replace_range(start..start + "#[cfg(test)]".len(), "");
            continue;
        }
        let open = start + text[start..].find('{').unwrap();
        let mut depth = 0usize;
        let mut end = text.len();
        for (i, c) in text[open..].char_indices() {
            match c {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    if depth == 0 {
                        end = open + i + 1;
                        break;
                    }
                }
                _ => {}
            }
        }
        text.replace_range(start..end, "");
    }
    text
}

/// The paths of a `use` tree (`a::{b, c::{d, e as f}}` → `a::b`,
/// `a::c::d`, `a::c::e`).
fn expand(tree: &str) -> Vec<String> {
    let tree: String = tree.split_whitespace().collect::<Vec<_>>().join(" ");
    let tree = tree.trim();
    let Some(open) = tree.find("::{") else {
        let path = tree.split(" as ").next().unwrap_or(tree);
        return vec![path.replace(' ', "")];
    };
    let prefix = &tree[..open];
    let inner = &tree[open + 3..tree.len() - 1];
    let (mut parts, mut depth, mut current) = (Vec::new(), 0i32, String::new());
    for c in inner.chars() {
        match c {
            '{' => depth += 1,
            '}' => depth -= 1,
            _ => {}
        }
        if c == ',' && depth == 0 {
            parts.push(std::mem::take(&mut current));
        } else {
            current.push(c);
        }
    }
    parts.push(current);
    let mut out = Vec::new();
    for part in parts.iter().map(|p| p.trim()).filter(|p| !p.is_empty()) {
        if part == "self" {
            out.push(prefix.replace(' ', ""));
        } else {
            out.extend(expand(part).into_iter().map(|p| format!("{prefix}::{p}")));
        }
    }
    out
}

/// `use` statements of `text`: (is `pub use`, its paths).
fn uses(text: &str) -> Vec<(bool, Vec<String>)> {
    let mut out = Vec::new();
    let mut rest = text;
    while let Some(at) = rest.find("use ") {
        let before = &rest[..at];
        let word_start =
            at == 0 || !rest[..at].ends_with(|c: char| c.is_alphanumeric() || c == '_');
        let Some(end) = rest[at..].find(';') else {
            break;
        };
        if word_start {
            let line_start = before.rfind(['\n', ';', '{', '}']).map_or(0, |i| i + 1);
            let public = before[line_start..].trim_start().starts_with("pub");
            out.push((public, expand(&rest[at + 4..at + end])));
        }
        rest = &rest[at + end + 1..];
    }
    out
}

/// Qualified paths (`a::b::c`) outside `use` statements.
fn qualified(text: &str) -> Vec<String> {
    let bytes: Vec<char> = text.chars().collect();
    let mut out = Vec::new();
    let mut i = 0;
    let ident = |c: char| c.is_alphanumeric() || c == '_';
    while i < bytes.len() {
        if ident(bytes[i]) && (i == 0 || !(ident(bytes[i - 1]) || bytes[i - 1] == ':')) {
            let mut j = i;
            while j < bytes.len()
                && (ident(bytes[j]) || (bytes[j] == ':' && bytes.get(j + 1) == Some(&':')))
            {
                j += if bytes[j] == ':' { 2 } else { 1 };
            }
            let path: String = bytes[i..j].iter().collect();
            let path = path.trim_end_matches(':');
            if path.contains("::") {
                out.push(path.to_owned());
            }
            i = j.max(i + 1);
        } else {
            i += 1;
        }
    }
    out
}

pub struct Graph {
    pub files: usize,
    pub edges: BTreeMap<Module, BTreeSet<Module>>,
}

pub fn graph(src: &Path) -> Graph {
    let mut paths = Vec::new();
    crate::architecture::sources(src, &mut paths);
    let texts: HashMap<Module, String> = paths
        .iter()
        .filter(|p| p.extension().is_some_and(|e| e == "rs"))
        .map(|p| {
            (
                module_of(src, p),
                strip(&std::fs::read_to_string(p).unwrap()),
            )
        })
        .collect();
    let mut aliases: HashMap<Module, HashMap<String, Vec<String>>> = HashMap::new();
    for (module, text) in &texts {
        for (public, paths) in uses(text) {
            for path in paths.into_iter().filter(|_| public) {
                let segments: Vec<String> = path.split("::").map(str::to_owned).collect();
                let name = segments.last().unwrap().clone();
                if name != "*" {
                    aliases
                        .entry(module.clone())
                        .or_default()
                        .insert(name, segments);
                }
            }
        }
    }
    let resolve = |from: &Module, segments: &[String]| -> Option<Module> {
        fn walk(
            texts: &HashMap<Module, String>,
            aliases: &HashMap<Module, HashMap<String, Vec<String>>>,
            from: &Module,
            segments: &[String],
            depth: usize,
        ) -> Option<Module> {
            let (mut current, rest): (Module, &[String]) = match segments.first()?.as_str() {
                "crate" => (Vec::new(), &segments[1..]),
                "self" => (from.clone(), &segments[1..]),
                "super" => {
                    let mut base = from.clone();
                    let mut k = 0;
                    while segments.get(k).is_some_and(|s| s == "super") {
                        base.pop();
                        k += 1;
                    }
                    (base, &segments[k..])
                }
                first => {
                    let mut child = from.clone();
                    child.push(first.to_owned());
                    if !texts.contains_key(&child) {
                        return None;
                    }
                    (from.clone(), segments)
                }
            };
            for segment in rest {
                let mut child = current.clone();
                child.push(segment.clone());
                if texts.contains_key(&child) {
                    current = child;
                } else if let Some(target) = aliases.get(&current).and_then(|a| a.get(segment)) {
                    if depth < 10 {
                        return walk(texts, aliases, &current, target, depth + 1).or(Some(current));
                    }
                    break;
                } else {
                    break;
                }
            }
            Some(current)
        }
        walk(&texts, &aliases, from, segments, 0)
    };
    let mut edges: BTreeMap<Module, BTreeSet<Module>> = BTreeMap::new();
    for (module, text) in &texts {
        let mut named: Vec<String> = Vec::new();
        let mut without_reexports = text.clone();
        for (public, paths) in uses(text) {
            if !public {
                named.extend(paths);
            }
        }
        // Re-exports name nothing this file uses.
        while let Some(at) = without_reexports
            .find("pub use ")
            .or_else(|| without_reexports.find("pub(crate) use "))
        {
            let end = at + without_reexports[at..].find(';').unwrap_or(0);
            without_reexports.replace_range(at..=end, "");
        }
        named.extend(qualified(&without_reexports));
        for path in named {
            let segments: Vec<String> = path.split("::").map(str::to_owned).collect();
            if let Some(target) = resolve(module, &segments) {
                if &target != module && !target.is_empty() {
                    edges.entry(module.clone()).or_default().insert(target);
                }
            }
        }
    }
    Graph {
        files: texts.len(),
        edges,
    }
}

/// The strongly connected components of more than one file (Tarjan).
pub fn circles(graph: &Graph) -> Vec<Vec<Module>> {
    struct State<'a> {
        edges: &'a BTreeMap<Module, BTreeSet<Module>>,
        index: HashMap<&'a Module, usize>,
        low: HashMap<&'a Module, usize>,
        stack: Vec<&'a Module>,
        on_stack: BTreeSet<&'a Module>,
        out: Vec<Vec<Module>>,
    }
    fn visit<'a>(s: &mut State<'a>, v: &'a Module) {
        let n = s.index.len();
        s.index.insert(v, n);
        s.low.insert(v, n);
        s.stack.push(v);
        s.on_stack.insert(v);
        if let Some(targets) = s.edges.get(v) {
            for w in targets {
                if !s.index.contains_key(w) {
                    visit(s, w);
                    let low = s.low[v].min(s.low[w]);
                    s.low.insert(v, low);
                } else if s.on_stack.contains(w) {
                    let low = s.low[v].min(s.index[w]);
                    s.low.insert(v, low);
                }
            }
        }
        if s.low[v] == s.index[v] {
            let mut component = Vec::new();
            while let Some(w) = s.stack.pop() {
                s.on_stack.remove(w);
                component.push(w.clone());
                if w == v {
                    break;
                }
            }
            if component.len() > 1 {
                component.sort();
                s.out.push(component);
            }
        }
    }
    let mut state = State {
        edges: &graph.edges,
        index: HashMap::new(),
        low: HashMap::new(),
        stack: Vec::new(),
        on_stack: BTreeSet::new(),
        out: Vec::new(),
    };
    for v in graph.edges.keys() {
        if !state.index.contains_key(v) {
            visit(&mut state, v);
        }
    }
    state.out
}
