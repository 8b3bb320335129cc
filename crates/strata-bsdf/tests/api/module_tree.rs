//! The library's modules form a one-way tree: no file depends, directly or
//! through others, on a file that depends on it (docs/architecture.md,
//! *Module map of the library*).
//!
//! The test reads every `.rs` file under `src/`, maps it to its module path
//! (`a/mod.rs` and `a.rs` are `a`, `lib.rs` the crate root) and collects the
//! files it names: the paths of its `use` and `pub use` declarations (grouped
//! ones included), and the paths in its code that start with `crate::`,
//! `super::`, `self::`, a child module's name or the name a `use` gave a
//! module. A path counts as a dependency on the file that defines the
//! deepest module it names (`crate::estimator::events::MAX_EVENTS` on
//! `estimator/events.rs`, `crate::estimator::Settings` on
//! `estimator/mod.rs`). Comments (doc comments and their links included),
//! strings and character literals are skipped, and so are `#[cfg(test)]`
//! modules: they are tests, compiled apart from the library. Declaring a
//! module (`mod a;`) is not a dependency; naming an item of it is.

use std::collections::{BTreeMap, BTreeSet, VecDeque};
use std::path::{Path, PathBuf};

/// A module's path from the crate root (`[]` is the root).
type ModPath = Vec<String>;

/// A token of Rust source, comments, literals and whitespace left out.
#[derive(Clone, Debug, PartialEq)]
enum Tok {
    Ident(String),
    /// `::`
    PathSep,
    Punct(char),
}

/// The tokens of `src` with their line numbers.
fn tokenize(src: &str) -> Vec<(Tok, usize)> {
    let c: Vec<char> = src.chars().collect();
    let mut out = Vec::new();
    let mut line = 1;
    let mut i = 0;
    // Skips from `i` (just past an opening quote) to just past the closing
    // quote `q`, over backslash escapes; counts lines.
    let skip_quoted = |i: &mut usize, line: &mut usize, q: char| {
        while *i < c.len() && c[*i] != q {
            if c[*i] == '\\' {
                *i += 1;
            }
            if *i < c.len() && c[*i] == '\n' {
                *line += 1;
            }
            *i += 1;
        }
        *i += 1;
    };
    while i < c.len() {
        let ch = c[i];
        let next = c.get(i + 1).copied();
        if ch == '\n' {
            line += 1;
            i += 1;
        } else if ch.is_whitespace() {
            i += 1;
        } else if ch == '/' && next == Some('/') {
            while i < c.len() && c[i] != '\n' {
                i += 1;
            }
        } else if ch == '/' && next == Some('*') {
            // Block comments nest.
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
                    if c[i] == '\n' {
                        line += 1;
                    }
                    i += 1;
                }
            }
        } else if ch == '"' {
            i += 1;
            skip_quoted(&mut i, &mut line, '"');
        } else if ch == '\'' {
            // A character literal ('a', '\n', '\'') or a lifetime or label ('a).
            if next == Some('\\') {
                i += 2;
                skip_quoted(&mut i, &mut line, '\'');
            } else if c.get(i + 2) == Some(&'\'') {
                i += 3;
            } else {
                i += 1;
                while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
                    i += 1;
                }
            }
        } else if ch.is_ascii_digit() {
            while i < c.len()
                && (c[i].is_alphanumeric()
                    || c[i] == '_'
                    || (c[i] == '.' && c.get(i + 1).is_some_and(|d| d.is_ascii_digit())))
            {
                i += 1;
            }
        } else if ch.is_alphabetic() || ch == '_' {
            let start = i;
            while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
                i += 1;
            }
            let word: String = c[start..i].iter().collect();
            let at = c.get(i).copied();
            let prefix = matches!(word.as_str(), "b" | "c" | "r" | "br" | "cr");
            if prefix && word.ends_with('r') && matches!(at, Some('"') | Some('#')) {
                // A raw string r"…" or r#"…"#, or a raw identifier r#name.
                let hashes = c[i..].iter().take_while(|&&h| h == '#').count();
                if c.get(i + hashes) == Some(&'"') {
                    i += hashes + 1;
                    // The string ends at a quote followed by as many hashes.
                    let closes = |i: usize| {
                        c[i] == '"'
                            && c.len() > i + hashes
                            && c[i + 1..=i + hashes].iter().all(|&h| h == '#')
                    };
                    while i < c.len() && !closes(i) {
                        if c[i] == '\n' {
                            line += 1;
                        }
                        i += 1;
                    }
                    i += 1 + hashes;
                } else {
                    // r#name: the identifier after the hash.
                    i += 1;
                    let s = i;
                    while i < c.len() && (c[i].is_alphanumeric() || c[i] == '_') {
                        i += 1;
                    }
                    out.push((Tok::Ident(c[s..i].iter().collect()), line));
                }
            } else if prefix && at == Some('"') {
                // b"…", c"…"
                i += 1;
                skip_quoted(&mut i, &mut line, '"');
            } else if word == "b" && at == Some('\'') {
                // b'…'
                i += 1;
                skip_quoted(&mut i, &mut line, '\'');
            } else {
                out.push((Tok::Ident(word), line));
            }
        } else if ch == ':' && next == Some(':') {
            out.push((Tok::PathSep, line));
            i += 2;
        } else {
            out.push((Tok::Punct(ch), line));
            i += 1;
        }
    }
    out
}

/// One file's reference to a module: the path as written, where, and the
/// module it resolves to.
#[derive(Clone, Debug)]
struct Reference {
    line: usize,
    written: String,
    target: ModPath,
}

fn is_ident(t: Option<&(Tok, usize)>, s: &str) -> bool {
    matches!(t, Some((Tok::Ident(w), _)) if w == s)
}

fn is_punct(t: Option<&(Tok, usize)>, p: char) -> bool {
    matches!(t, Some((Tok::Punct(q), _)) if *q == p)
}

/// The index just past the group that opens at `i` (`{`, `[` or `(`).
fn skip_group(toks: &[(Tok, usize)], mut i: usize) -> usize {
    let mut depth = 0i32;
    while i < toks.len() {
        match toks[i].0 {
            Tok::Punct('{' | '[' | '(') => depth += 1,
            Tok::Punct('}' | ']' | ')') => {
                depth -= 1;
                if depth == 0 {
                    return i + 1;
                }
            }
            _ => {}
        }
        i += 1;
    }
    i
}

/// If `#[cfg(test)]` starts at `i`, the index just past the item it marks
/// when that item is a module (a test module, left out); otherwise `None`.
fn skip_test_module(toks: &[(Tok, usize)], i: usize) -> Option<usize> {
    let cfg_test = [
        Tok::Punct('#'),
        Tok::Punct('['),
        Tok::Ident("cfg".into()),
        Tok::Punct('('),
        Tok::Ident("test".into()),
        Tok::Punct(')'),
        Tok::Punct(']'),
    ];
    if toks.len() < i + cfg_test.len()
        || toks[i..i + cfg_test.len()]
            .iter()
            .zip(&cfg_test)
            .any(|(a, b)| a.0 != *b)
    {
        return None;
    }
    let mut j = i + cfg_test.len();
    // Further attributes, then the visibility.
    while is_punct(toks.get(j), '#') {
        j = skip_group(toks, j + 1);
    }
    if is_ident(toks.get(j), "pub") {
        j += 1;
        if is_punct(toks.get(j), '(') {
            j = skip_group(toks, j);
        }
    }
    if !is_ident(toks.get(j), "mod") {
        return None;
    }
    j += 2;
    if is_punct(toks.get(j), ';') {
        Some(j + 1)
    } else {
        Some(skip_group(toks, j))
    }
}

/// The leaves of the use tree that starts at `*i` under `prefix`, each with
/// its name in scope (the last segment or its `as` name; `None` for a glob);
/// leaves `*i` past the tree.
fn use_tree(
    toks: &[(Tok, usize)],
    i: &mut usize,
    prefix: Vec<String>,
    out: &mut Vec<(Vec<String>, Option<String>)>,
) {
    let mut path = prefix;
    loop {
        match toks.get(*i).map(|t| &t.0) {
            Some(Tok::Punct('{')) => {
                *i += 1;
                while *i < toks.len() && !is_punct(toks.get(*i), '}') {
                    use_tree(toks, i, path.clone(), out);
                    if is_punct(toks.get(*i), ',') {
                        *i += 1;
                    }
                }
                *i += 1;
                return;
            }
            Some(Tok::Punct('*')) => {
                *i += 1;
                out.push((path, None));
                return;
            }
            Some(Tok::PathSep) => *i += 1,
            Some(Tok::Ident(w)) => {
                *i += 1;
                if w == "self" && !path.is_empty() && !is_punct_sep(toks.get(*i)) {
                    // `a::{self, b}` names `a` itself.
                } else {
                    path.push(w.clone());
                }
                if is_punct_sep(toks.get(*i)) {
                    continue;
                }
                let mut name = path.last().cloned();
                if is_ident(toks.get(*i), "as") {
                    name = match toks.get(*i + 1) {
                        Some((Tok::Ident(a), _)) => Some(a.clone()),
                        _ => None,
                    };
                    *i += 2;
                }
                out.push((path, name));
                return;
            }
            // `;`, `,`, `}` or the end: a malformed tree; stop here.
            _ => return,
        }
    }
}

fn is_punct_sep(t: Option<&(Tok, usize)>) -> bool {
    matches!(t, Some((Tok::PathSep, _)))
}

/// The crate's modules: each module path and the file that defines it.
struct Crate {
    files: BTreeMap<PathBuf, ModPath>,
    modules: BTreeMap<ModPath, PathBuf>,
}

impl Crate {
    /// The module path of a file under `src`, by the file layout.
    fn file_module(rel: &Path) -> ModPath {
        let mut parts: Vec<String> = rel
            .iter()
            .map(|p| p.to_string_lossy().into_owned())
            .collect();
        let last = parts.pop().expect("a file name");
        let stem = last.trim_end_matches(".rs");
        if !(parts.is_empty() && stem == "lib") && stem != "mod" {
            parts.push(stem.to_string());
        }
        parts
    }

    /// Resolves `segments`, written in module `from`, to the deepest module
    /// it names, and whether every segment is a module; `None` when it names
    /// no module of the crate (another crate's path, a local item, a type's
    /// associated item).
    fn resolve(
        &self,
        from: &ModPath,
        aliases: &BTreeMap<(ModPath, String), ModPath>,
        segments: &[String],
    ) -> Option<(ModPath, bool)> {
        let (first, rest) = segments.split_first()?;
        let mut cur: ModPath = match first.as_str() {
            "crate" => Vec::new(),
            "self" => from.clone(),
            "super" => from[..from.len().checked_sub(1)?].to_vec(),
            name => {
                let mut child = from.clone();
                child.push(name.to_string());
                if self.modules.contains_key(&child) {
                    child
                } else {
                    aliases.get(&(from.clone(), name.to_string()))?.clone()
                }
            }
        };
        let mut rest = rest;
        while let Some((seg, tail)) = rest.split_first() {
            if seg == "super" {
                cur.pop()?;
            } else if seg != "self" {
                let mut next = cur.clone();
                next.push(seg.clone());
                if !self.modules.contains_key(&next) {
                    break;
                }
                cur = next;
            }
            rest = tail;
        }
        Some((cur, rest.is_empty()))
    }

    /// The inline modules (`mod a { … }`, not `#[cfg(test)]`) a file defines
    /// in module `base`, with their paths.
    fn inline_modules(toks: &[(Tok, usize)], base: &ModPath) -> Vec<ModPath> {
        let mut found = Vec::new();
        let mut stack: Vec<(ModPath, i32)> = Vec::new();
        let mut depth = 0;
        let mut i = 0;
        while i < toks.len() {
            if let Some(j) = skip_test_module(toks, i) {
                i = j;
                continue;
            }
            match &toks[i].0 {
                Tok::Ident(w) if w == "mod" => {
                    if let (Some((Tok::Ident(name), _)), true) =
                        (toks.get(i + 1), is_punct(toks.get(i + 2), '{'))
                    {
                        let mut path = stack.last().map_or(base.clone(), |s| s.0.clone());
                        path.push(name.clone());
                        found.push(path.clone());
                        depth += 1;
                        stack.push((path, depth));
                        i += 3;
                        continue;
                    }
                }
                Tok::Punct('{') => depth += 1,
                Tok::Punct('}') => {
                    if stack.last().is_some_and(|s| s.1 == depth) {
                        stack.pop();
                    }
                    depth -= 1;
                }
                _ => {}
            }
            i += 1;
        }
        found
    }

    /// Reads every `.rs` file under `src`.
    fn read(src: &Path) -> (Crate, BTreeMap<PathBuf, Vec<(Tok, usize)>>) {
        let mut stack = vec![src.to_path_buf()];
        let mut texts = BTreeMap::new();
        while let Some(dir) = stack.pop() {
            for entry in std::fs::read_dir(&dir).expect("read src") {
                let path = entry.expect("dir entry").path();
                if path.is_dir() {
                    stack.push(path);
                } else if path.extension().is_some_and(|e| e == "rs") {
                    let rel = path.strip_prefix(src).expect("under src").to_path_buf();
                    let text = std::fs::read_to_string(&path).expect("read file");
                    texts.insert(rel, tokenize(&text));
                }
            }
        }
        Self::from_tokens(texts)
    }

    fn from_tokens(
        texts: BTreeMap<PathBuf, Vec<(Tok, usize)>>,
    ) -> (Crate, BTreeMap<PathBuf, Vec<(Tok, usize)>>) {
        let mut files = BTreeMap::new();
        let mut modules = BTreeMap::new();
        for (rel, toks) in &texts {
            let m = Self::file_module(rel);
            for inline in Self::inline_modules(toks, &m) {
                modules.insert(inline, rel.clone());
            }
            files.insert(rel.clone(), m.clone());
            modules.insert(m, rel.clone());
        }
        (Crate { files, modules }, texts)
    }

    /// The modules a file names, in order.
    fn references(&self, rel: &Path, toks: &[(Tok, usize)]) -> Vec<Reference> {
        let base = self.files[rel].clone();
        let mut aliases: BTreeMap<(ModPath, String), ModPath> = BTreeMap::new();
        let mut refs = Vec::new();
        let mut stack: Vec<(ModPath, i32)> = Vec::new();
        let mut depth = 0;
        let mut i = 0;
        while i < toks.len() {
            if let Some(j) = skip_test_module(toks, i) {
                i = j;
                continue;
            }
            let here = stack.last().map_or(base.clone(), |s| s.0.clone());
            let line = toks[i].1;
            // A path's first segment follows neither `::` nor `.` (a method's
            // turbofish, `x.f::<T>()`).
            let after_sep = i > 0 && matches!(toks[i - 1].0, Tok::PathSep | Tok::Punct('.'));
            match &toks[i].0 {
                Tok::Ident(w) if w == "mod" && is_punct(toks.get(i + 2), '{') => {
                    if let Some((Tok::Ident(name), _)) = toks.get(i + 1) {
                        let mut path = here.clone();
                        path.push(name.clone());
                        depth += 1;
                        stack.push((path, depth));
                        i += 3;
                        continue;
                    }
                }
                Tok::Ident(w) if w == "use" && !is_punct(toks.get(i + 1), '<') && !after_sep => {
                    i += 1;
                    let mut leaves = Vec::new();
                    use_tree(toks, &mut i, Vec::new(), &mut leaves);
                    for (path, name) in leaves {
                        let Some((target, whole)) = self.resolve(&here, &aliases, &path) else {
                            continue;
                        };
                        // A leaf that is a module gives its name to it.
                        if let (true, Some(name)) = (whole, name) {
                            aliases.insert((here.clone(), name), target.clone());
                        }
                        refs.push(Reference {
                            line,
                            written: format!("use {}", path.join("::")),
                            target,
                        });
                    }
                    continue;
                }
                Tok::Ident(first) if !after_sep && is_punct_sep(toks.get(i + 1)) => {
                    let mut segments = vec![first.clone()];
                    let mut j = i + 1;
                    while is_punct_sep(toks.get(j)) {
                        match toks.get(j + 1) {
                            Some((Tok::Ident(s), _)) => {
                                segments.push(s.clone());
                                j += 2;
                            }
                            _ => break,
                        }
                    }
                    if let Some((target, _)) = self.resolve(&here, &aliases, &segments) {
                        refs.push(Reference {
                            line,
                            written: segments.join("::"),
                            target,
                        });
                    }
                    i = j;
                    continue;
                }
                Tok::Punct('{') => depth += 1,
                Tok::Punct('}') => {
                    if stack.last().is_some_and(|s| s.1 == depth) {
                        stack.pop();
                    }
                    depth -= 1;
                }
                _ => {}
            }
            i += 1;
        }
        refs
    }

    /// The file graph: for each file, the files it depends on, each with
    /// the first reference that makes it so.
    fn graph(
        &self,
        texts: &BTreeMap<PathBuf, Vec<(Tok, usize)>>,
    ) -> BTreeMap<PathBuf, BTreeMap<PathBuf, Reference>> {
        let mut graph = BTreeMap::new();
        for (rel, toks) in texts {
            let deps: &mut BTreeMap<PathBuf, Reference> = graph.entry(rel.clone()).or_default();
            for r in self.references(rel, toks) {
                let file = &self.modules[&r.target];
                if file != rel {
                    deps.entry(file.clone()).or_insert(r);
                }
            }
        }
        graph
    }
}

/// The strongly connected components of more than one file (Tarjan).
fn cycles_of<T: Ord + Clone>(graph: &BTreeMap<T, BTreeMap<T, Reference>>) -> Vec<Vec<T>> {
    struct State<T> {
        index: BTreeMap<T, usize>,
        low: BTreeMap<T, usize>,
        on: BTreeSet<T>,
        stack: Vec<T>,
        out: Vec<Vec<T>>,
    }
    fn visit<T: Ord + Clone>(g: &BTreeMap<T, BTreeMap<T, Reference>>, v: &T, s: &mut State<T>) {
        let n = s.index.len();
        s.index.insert(v.clone(), n);
        s.low.insert(v.clone(), n);
        s.stack.push(v.clone());
        s.on.insert(v.clone());
        for w in g.get(v).into_iter().flat_map(|d| d.keys()) {
            if !s.index.contains_key(w) {
                visit(g, w, s);
                let lw = s.low[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(lw);
            } else if s.on.contains(w) {
                let iw = s.index[w];
                let lv = s.low.get_mut(v).expect("visited");
                *lv = (*lv).min(iw);
            }
        }
        if s.low[v] == s.index[v] {
            let mut comp = Vec::new();
            loop {
                let w = s.stack.pop().expect("on the stack");
                s.on.remove(&w);
                comp.push(w.clone());
                if w == *v {
                    break;
                }
            }
            if comp.len() > 1 {
                comp.sort();
                s.out.push(comp);
            }
        }
    }
    let mut s = State {
        index: BTreeMap::new(),
        low: BTreeMap::new(),
        on: BTreeSet::new(),
        stack: Vec::new(),
        out: Vec::new(),
    };
    for v in graph.keys() {
        if !s.index.contains_key(v) {
            visit(graph, v, &mut s);
        }
    }
    s.out.sort();
    s.out
}

/// A shortest cycle through `start` within `comp`.
fn cycle_through<T: Ord + Clone>(
    graph: &BTreeMap<T, BTreeMap<T, Reference>>,
    comp: &[T],
    start: &T,
) -> Vec<T> {
    let inside: BTreeSet<&T> = comp.iter().collect();
    let mut prev: BTreeMap<T, T> = BTreeMap::new();
    let mut queue = VecDeque::from([start.clone()]);
    while let Some(v) = queue.pop_front() {
        for w in graph[&v].keys().filter(|w| inside.contains(w)) {
            if w == start {
                let mut path = vec![v.clone()];
                while let Some(p) = prev.get(path.last().expect("nonempty")) {
                    path.push(p.clone());
                }
                path.reverse();
                return path;
            }
            if !prev.contains_key(w) && w != start {
                prev.insert(w.clone(), v.clone());
                queue.push_back(w.clone());
            }
        }
    }
    vec![start.clone()]
}

/// The report of every cycle of `graph`: each strongly connected component
/// (files that all reach one another), and in it the shortest cycle through
/// each of its files, with the line that makes each step.
fn report(graph: &BTreeMap<PathBuf, BTreeMap<PathBuf, Reference>>) -> Option<String> {
    let comps = cycles_of(graph);
    if comps.is_empty() {
        return None;
    }
    let mut msg = format!(
        "{} group(s) of files that import one another (a one-way tree has none):\n",
        comps.len()
    );
    for comp in &comps {
        let names: Vec<String> = comp.iter().map(|p| p.display().to_string()).collect();
        msg += &format!("\n* {} files: {}\n", comp.len(), names.join(", "));
        let mut seen = BTreeSet::new();
        for file in comp {
            let mut cycle = cycle_through(graph, comp, file);
            // The same cycle found from another of its files is shown once.
            let first = (0..cycle.len()).min_by_key(|&k| &cycle[k]).unwrap_or(0);
            cycle.rotate_left(first);
            if !seen.insert(cycle.clone()) {
                continue;
            }
            msg += "  cycle:\n";
            for (k, a) in cycle.iter().enumerate() {
                let b = &cycle[(k + 1) % cycle.len()];
                let r = &graph[a][b];
                msg += &format!(
                    "    {} -> {}  (line {}: {})\n",
                    a.display(),
                    b.display(),
                    r.line,
                    r.written
                );
            }
        }
    }
    Some(msg)
}

/// The graph of a crate given as (file, source) pairs.
fn graph_of(sources: &[(&str, &str)]) -> BTreeMap<PathBuf, BTreeMap<PathBuf, Reference>> {
    let texts = sources
        .iter()
        .map(|(p, s)| (PathBuf::from(p), tokenize(s)))
        .collect();
    let (krate, texts) = Crate::from_tokens(texts);
    krate.graph(&texts)
}

fn deps_of(graph: &BTreeMap<PathBuf, BTreeMap<PathBuf, Reference>>, file: &str) -> Vec<String> {
    graph[Path::new(file)]
        .keys()
        .map(|p| p.display().to_string())
        .collect()
}

#[test]
fn the_library_has_no_import_cycle() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let (krate, texts) = Crate::read(&src);
    assert!(
        texts.len() > 40,
        "read {} files under {}",
        texts.len(),
        src.display()
    );
    let graph = krate.graph(&texts);
    // The scan sees the dependencies the library is built on.
    assert!(deps_of(&graph, "lib.rs").contains(&"api/mod.rs".to_string()));
    assert!(deps_of(&graph, "estimator/wavefront/mod.rs").contains(&"lane/mod.rs".to_string()));
    if let Some(msg) = report(&graph) {
        panic!("{msg}");
    }
}

#[test]
fn the_scan_reads_grouped_imports_and_skips_comments_strings_and_tests() {
    let graph = graph_of(&[
        (
            "lib.rs",
            "pub mod a; pub mod b; pub mod c; pub mod d; mod e;",
        ),
        (
            "a/mod.rs",
            r##"
            //! Doc: crate::b::X is not a use.
            pub mod inner;
            use crate::{b::{self, X}, c::{Y as Z}};
            /* nested /* crate::d */ comment */
            const S: &str = "crate::d::W";
            const R: &str = r#"super::d "quoted" "#;
            const C: char = '"';
            fn f<'a>(x: &'a str) -> &'a str { let _ = b::f(); let _ = inner::g(); x }
            #[cfg(test)]
            mod tests { use crate::e::T; fn t() { crate::d::f(); } }
            "##,
        ),
        ("a/inner.rs", "pub fn g() {}"),
        ("b.rs", "pub struct X; pub fn f() {}"),
        (
            "c.rs",
            "pub struct Y; mod field { use super::Y; } fn h() { std::mem::drop(1); }",
        ),
        ("d.rs", "pub fn f() {}"),
        ("e.rs", "pub struct T;"),
    ]);
    assert_eq!(deps_of(&graph, "a/mod.rs"), ["a/inner.rs", "b.rs", "c.rs"]);
    assert!(deps_of(&graph, "c.rs").is_empty());
    assert!(report(&graph).is_none());
}

#[test]
fn the_scan_reports_a_cycle_through_super_and_a_reexport() {
    // `a/mod.rs` re-exports its child, and the child names the parent's item.
    let graph = graph_of(&[
        ("lib.rs", "pub mod a; pub use a::Top;"),
        ("a/mod.rs", "mod low; pub use low::L; pub struct Top;"),
        ("a/low.rs", "pub struct L(super::Top);"),
    ]);
    let msg = report(&graph).expect("a cycle");
    assert!(msg.contains("a/low.rs -> a/mod.rs"), "{msg}");
    assert!(msg.contains("a/mod.rs -> a/low.rs"), "{msg}");
    // A three-file cycle through qualified paths and a module alias.
    let graph = graph_of(&[
        ("lib.rs", "pub mod x; pub mod y; pub mod z;"),
        ("x.rs", "pub fn f() { crate::y::g() }"),
        ("y.rs", "use crate::z; pub fn g() { z::h() }"),
        ("z.rs", "pub fn h() { super::x::f() }"),
    ]);
    let msg = report(&graph).expect("a cycle");
    assert!(msg.contains("3 files: x.rs, y.rs, z.rs"), "{msg}");
}
