//! No `[[unroll]]` loop of a kernel leaves early. With a `break` or
//! `continue` in such a loop, lavapipe (Mesa 25) kept the arrays the loop
//! indexes by its counter in memory for the whole kernel (a blend lane's
//! pixels, a U-Net tile's outputs: an `alloca` of the whole array in the
//! LLVM IR that `GALLIVM_DEBUG=ir` prints), where unrolled code keeps them in
//! registers, and those kernels ran slower (docs/bench/splat.md, "Early exits
//! in unrolled loops"). Guard the work with an `if` instead; a `return` is
//! refused too.

use std::path::{Path, PathBuf};

/// Every `.comp` and `.glsl` file under `dir`.
fn sources(dir: &Path) -> Vec<PathBuf> {
    let mut out = Vec::new();
    let Ok(entries) = std::fs::read_dir(dir) else { return out };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            out.extend(sources(&path));
        } else if path.extension().is_some_and(|x| x == "comp" || x == "glsl") {
            out.push(path);
        }
    }
    out.sort();
    out
}

/// Whether `word` occurs in `code` as a whole word.
fn has_word(code: &str, word: &str) -> bool {
    code.match_indices(word).any(|(i, _)| {
        let before = code[..i].chars().next_back();
        let after = code[i + word.len()..].chars().next();
        let ident = |c: Option<char>| c.is_some_and(|c| c.is_ascii_alphanumeric() || c == '_');
        !ident(before) && !ident(after)
    })
}

/// `file:line` of every early exit whose innermost enclosing loop is marked
/// `[[unroll]]`. Loops are found by their `for`/`while` header opening a
/// brace on the same line (the kernels' style); comments are ignored.
fn early_exits_in_unrolled_loops(path: &Path, text: &str) -> Vec<String> {
    // (unrolled, brace depth outside the loop) of each open loop.
    let mut loops: Vec<(bool, i32)> = Vec::new();
    let mut depth = 0i32;
    let mut found = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let code = line.split("//").next().unwrap_or_default();
        if (has_word(code, "for") || has_word(code, "while")) && code.contains('{') {
            loops.push((code.contains("[[unroll]]"), depth));
        }
        let exits = ["break", "continue", "return"].iter().any(|w| has_word(code, w));
        if exits && loops.last().is_some_and(|l| l.0) {
            found.push(format!("{}:{}: {}", path.display(), n + 1, line.trim()));
        }
        for c in code.chars() {
            match c {
                '{' => depth += 1,
                '}' => {
                    depth -= 1;
                    while loops.last().is_some_and(|l| l.1 >= depth) {
                        loops.pop();
                    }
                }
                _ => {}
            }
        }
    }
    found
}

#[test]
fn no_unrolled_loop_leaves_early() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("shaders");
    let files = sources(&dir);
    assert!(files.len() > 50, "found only {} shader sources under {}", files.len(), dir.display());
    let mut found = Vec::new();
    for path in &files {
        let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        found.extend(early_exits_in_unrolled_loops(path, &text));
    }
    assert!(found.is_empty(), "early exits in [[unroll]] loops (guard with an `if`):\n{}", found.join("\n"));
}

#[test]
fn the_scan_finds_early_exits_and_only_in_unrolled_loops() {
    let path = Path::new("example.comp");
    let text = "void main() {\n\
                \x20   [[unroll]] for (uint k = 0u; k < N; k++) {\n\
                \x20       if (k >= n) continue;  // flagged\n\
                \x20       for (uint j = 0u; j < m; j++) {\n\
                \x20           if (j > 3u) break;  // a plain inner loop: fine\n\
                \x20       }\n\
                \x20       if (k == 2u) { return; }  // flagged\n\
                \x20   }\n\
                \x20   for (uint j = 0u; j < m; j++) { if (j > 3u) break; }\n\
                \x20   // [[unroll]] for (;;) { break; } (a comment)\n\
                \x20   [[unroll]] for (uint k = 0u; k < N; k++) {\n\
                \x20       breakpoint_count += 1u;  // not a keyword\n\
                \x20   }\n\
                }\n";
    let found = early_exits_in_unrolled_loops(path, text);
    assert_eq!(found.len(), 2, "{found:?}");
    assert!(found[0].starts_with("example.comp:3:") && found[1].starts_with("example.comp:7:"), "{found:?}");
}
