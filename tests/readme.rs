//! The README's "As a dependency" snippet names no crate but `brdf_sampling` (and std): a new
//! user's crate has that one dependency line and nothing else, and the doc test that compiles
//! the snippet cannot see a missing one (the facade's own dependencies are in scope there).

/// The snippet: the first ```rust block after the "As a dependency" heading.
fn snippet() -> String {
    let readme =
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/README.md")).unwrap();
    let section = &readme[readme.find("## As a dependency").expect("the section")..];
    let start = section.find("```rust\n").expect("a rust block") + 8;
    let end = start + section[start..].find("```").expect("its end");
    section[start..end].to_string()
}

/// Every identifier that starts a path (`name::`) in `code`.
fn path_roots(code: &str) -> Vec<String> {
    let b = code.as_bytes();
    let mut out = Vec::new();
    for (i, _) in code.match_indices("::") {
        let mut j = i;
        while j > 0 && (b[j - 1].is_ascii_alphanumeric() || b[j - 1] == b'_') {
            j -= 1;
        }
        // A path's first segment: not preceded by another `::`.
        if j < i && !(j >= 2 && &code[j - 2..j] == "::") {
            out.push(code[j..i].to_string());
        }
    }
    out
}

#[test]
fn the_dependency_snippet_names_no_other_crate() {
    let code = snippet();
    let uses: Vec<&str> = code
        .lines()
        .filter(|l| l.trim_start().starts_with("use "))
        .collect();
    assert!(!uses.is_empty());
    for u in &uses {
        assert!(u.trim_start().starts_with("use brdf_sampling::"), "{u}");
    }
    // The names the `use` lines bring in (every identifier in them).
    let imported: Vec<String> = uses
        .iter()
        .flat_map(|u| u.split(|c: char| !(c.is_ascii_alphanumeric() || c == '_')))
        .filter(|s| !s.is_empty())
        .map(str::to_string)
        .collect();
    for root in path_roots(&code) {
        assert!(
            root == "brdf_sampling" || root == "std" || root == "core" || imported.contains(&root),
            "the snippet names `{root}::`, which its one dependency line does not provide"
        );
    }
    // And the test itself can fail: the old snippet's `rand_pcg::Pcg64` would be caught.
    assert!(
        path_roots("let r = rand_pcg::Pcg64::seed_from_u64(7);").contains(&"rand_pcg".to_string())
    );
    assert!(!path_roots("use brdf_sampling::rng::Pcg64;").contains(&"rng".to_string()));
}
