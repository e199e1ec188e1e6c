//! Helpers shared by the meta crate's integration tests (`mod support;` in each).

/// The scenario's `skill_graph: ( … ),` block (empty when it has none): variants over fewer
/// skills drop it, since it names skills they leave out.
pub fn graph_block(text: &str) -> String {
    let Some(start) = text.find("    skill_graph: (") else { return String::new() };
    let end = start + text[start..].find("\n    ),\n").expect("the graph block closes") + "\n    ),\n".len();
    text[start..end].to_string()
}
