//! Helpers shared by the meta crate's integration tests (`mod support;` in each).

/// The scenario's `skill_graph: ( … ),` block (empty when it has none): variants over fewer
/// skills drop it, since it names skills they leave out.
#[allow(dead_code)]
pub fn graph_block(text: &str) -> String {
    let Some(start) = text.find("    skill_graph: (") else { return String::new() };
    let end = start + text[start..].find("\n    ),\n").expect("the graph block closes") + "\n    ),\n".len();
    text[start..end].to_string()
}

/// The default sitting scenario's text without its `stand` (the graph until stop 33), for tests
/// whose library holds the other skills only and whose option indices predate it.
#[allow(dead_code)]
pub fn without_stand(text: &str) -> String {
    let skills = "\"turn_right_wide\", \"stand\", \"sit\"],";
    let edges = "            (\"walk_to\", \"stand\"), (\"turn_left\", \"stand\"), (\"turn_right\", \"stand\"),\n            (\"turn_left_wide\", \"stand\"), (\"turn_right_wide\", \"stand\"),\n            (\"stand\", \"sit\"),\n";
    assert!(text.contains(skills) && text.contains(edges), "the default scenario's stand moved");
    text.replace(skills, "\"turn_right_wide\", \"sit\"],").replace(edges, "")
}
