//! [`SkillGraph`]: which skill may follow which, as a petgraph digraph over the scenario's skills.

use petgraph::graph::{DiGraph, NodeIndex};
use repertoire_scenes::scenario::Scenario;

/// The allowed skill transitions of a scenario. Option `k` of the meta-controller is skill
/// `names()[k]`; staying in the current skill is always allowed.
#[derive(Debug, Clone)]
pub struct SkillGraph {
    graph: DiGraph<String, ()>,
    start: Vec<bool>,
}

impl SkillGraph {
    /// The scenario's graph (validated with the scenario), or the complete graph over its
    /// skills when it declares none.
    pub fn of(scenario: &Scenario) -> Self {
        let names = &scenario.skills;
        let mut graph = DiGraph::new();
        let nodes: Vec<NodeIndex> = names.iter().map(|n| graph.add_node(n.clone())).collect();
        let id = |name: &str| names.iter().position(|n| n == name).expect("validated with the scenario");
        let start = match &scenario.skill_graph {
            Some(g) => {
                for (a, b) in &g.edges {
                    graph.update_edge(nodes[id(a)], nodes[id(b)], ());
                }
                names.iter().map(|n| g.start.contains(n)).collect()
            }
            None => {
                for &a in &nodes {
                    for &b in &nodes {
                        if a != b {
                            graph.add_edge(a, b, ());
                        }
                    }
                }
                vec![true; names.len()]
            }
        };
        SkillGraph { graph, start }
    }

    /// This graph restricted to `keep` (in this graph's order): the "one turn direction only"
    /// ablation. `Err` names a skill the graph lacks, or the start skills when `keep` drops them
    /// all (no episode could start).
    pub fn restricted(&self, keep: &[String]) -> Result<Self, RestrictError> {
        if let Some(missing) = keep.iter().find(|k| self.index(k).is_none()) {
            return Err(RestrictError::NotInGraph {
                skill: missing.clone(),
                graph: self.names().into_iter().map(String::from).collect(),
            });
        }
        let starts: Vec<&str> =
            self.names().into_iter().zip(&self.start).filter(|(_, s)| **s).map(|(n, _)| n).collect();
        if !starts.iter().any(|s| keep.iter().any(|k| k == s)) {
            return Err(RestrictError::NoStart {
                kept: keep.to_vec(),
                starts: starts.into_iter().map(String::from).collect(),
            });
        }
        let graph = self.graph.filter_map(|_, name| keep.contains(name).then(|| name.clone()), |_, &()| Some(()));
        let start = self
            .graph
            .node_indices()
            .filter(|n| keep.contains(&self.graph[*n]))
            .map(|n| self.start[n.index()])
            .collect();
        Ok(SkillGraph { graph, start })
    }

    /// A fixed-order chain: each skill may only hand over to the next.
    pub fn chain(names: &[&str]) -> Self {
        let mut graph = DiGraph::new();
        let nodes: Vec<NodeIndex> = names.iter().map(|n| graph.add_node((*n).to_string())).collect();
        for w in nodes.windows(2) {
            graph.add_edge(w[0], w[1], ());
        }
        let start = (0..names.len()).map(|k| k == 0).collect();
        SkillGraph { graph, start }
    }

    /// Skill names in option order.
    pub fn names(&self) -> Vec<&str> {
        self.graph.node_indices().map(|n| self.graph[n].as_str()).collect()
    }

    /// Number of skills.
    pub fn len(&self) -> usize {
        self.graph.node_count()
    }

    /// Whether the graph has no skills.
    pub fn is_empty(&self) -> bool {
        self.graph.node_count() == 0
    }

    /// The option index of skill `name`.
    pub fn index(&self, name: &str) -> Option<usize> {
        self.graph.node_indices().position(|n| self.graph[n] == name)
    }

    /// Writes which options may be chosen next into `mask`: after `current` (None at an
    /// episode's start), the start skills, else `current` itself and its successors.
    ///
    /// Panics when `mask` does not have one entry per skill of the graph.
    pub fn allowed(&self, current: Option<usize>, mask: &mut [bool]) {
        assert_eq!(
            mask.len(),
            self.len(),
            "an option mask for a graph of {} skills has {} entries",
            self.len(),
            mask.len()
        );
        match current {
            None => mask.copy_from_slice(&self.start),
            Some(c) => {
                mask.fill(false);
                mask[c] = true;
                for n in self.graph.neighbors(NodeIndex::new(c)) {
                    mask[n.index()] = true;
                }
            }
        }
    }

    /// Whether `to` may follow `from` (None: at the start).
    pub fn is_allowed(&self, from: Option<usize>, to: usize) -> bool {
        let mut mask = vec![false; self.len()];
        self.allowed(from, &mut mask);
        mask.get(to).copied().unwrap_or(false)
    }
}

/// Why [`SkillGraph::restricted`] cannot keep the skills it was given.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RestrictError {
    /// A skill the graph lacks.
    #[error("skill `{skill}` is not in the graph ({})", graph.join(", "))]
    NotInGraph {
        /// The skill.
        skill: String,
        /// The graph's skills.
        graph: Vec<String>,
    },
    /// The kept skills leave out every skill an episode may start with.
    #[error(
        "the skills kept ({}) leave out every start skill of the graph ({}): no episode could start; keep one of them, or give a fixed order with --chain",
        kept.join(", "),
        starts.join(", ")
    )]
    NoStart {
        /// The skills kept.
        kept: Vec<String>,
        /// The graph's start skills.
        starts: Vec<String>,
    },
}
