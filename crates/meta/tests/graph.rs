//! The skill graph of the default scenario and of fixed-order chains.

use rand::{Rng, SeedableRng};
use repertoire_meta::SkillGraph;
use repertoire_meta::graph::RestrictError;
use repertoire_scenes::ScenarioFile;

#[test]
fn the_default_graph_follows_the_scenario() {
    let s = ScenarioFile::builtin_default();
    let g = SkillGraph::of(&s.scenario);
    assert_eq!(g.names(), ["walk_to", "turn_left", "turn_right", "turn_left_wide", "turn_right_wide", "stand", "sit"]);
    let (walk, stand, sit) = (0, 5, 6);
    // The stand (stop 34) follows walk_to and every turn and leads only to the sit.
    assert!(g.is_allowed(Some(walk), stand) && g.is_allowed(Some(stand), sit) && !g.is_allowed(None, stand));
    for other in 0..=4 {
        assert!(g.is_allowed(Some(other), stand) && !g.is_allowed(Some(stand), other), "{}", g.names()[other]);
    }
    assert!(g.is_allowed(None, walk) && !g.is_allowed(None, sit), "episodes do not start seated");
    assert!(!g.is_allowed(Some(walk), sit), "sit only after a turn");
    for turn in 1..=4 {
        assert!(g.is_allowed(Some(walk), turn) && g.is_allowed(Some(turn), walk), "{}", g.names()[turn]);
        assert!(g.is_allowed(Some(turn), sit), "sit after {}", g.names()[turn]);
        assert!(!g.is_allowed(Some(sit), turn), "sitting is final");
    }
    assert!(g.is_allowed(Some(sit), sit) && !g.is_allowed(Some(sit), walk), "sitting is final");
}

#[test]
fn a_fixed_order_chain_never_allows_an_illegal_skill() {
    let g = SkillGraph::chain(&["walk_to", "turn_left", "sit"]);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let mut mask = vec![false; g.len()];
    // Random choices among the allowed options, many episodes: the visited order is always a
    // prefix of walk → turn_left → sit, each held for some ticks.
    for _ in 0..200 {
        let mut current = None;
        let mut visited: Vec<usize> = Vec::new();
        for _ in 0..30 {
            g.allowed(current, &mut mask);
            let allowed: Vec<usize> = (0..g.len()).filter(|&k| mask[k]).collect();
            let next = allowed[rng.random_range(0..allowed.len())];
            if current != Some(next) {
                visited.push(next);
            }
            current = Some(next);
        }
        assert_eq!(visited, (0..visited.len()).collect::<Vec<_>>(), "illegal order {visited:?}");
    }
}

#[test]
fn restricting_the_graph_keeps_its_edges_among_the_kept_skills() {
    let s = ScenarioFile::builtin_default();
    let g = SkillGraph::of(&s.scenario);
    let left = g.restricted(&["walk_to".into(), "turn_left".into(), "sit".into()]).expect("known skills");
    assert_eq!(left.names(), ["walk_to", "turn_left", "sit"]);
    assert!(left.is_allowed(Some(0), 1) && left.is_allowed(Some(1), 2) && !left.is_allowed(Some(0), 2));
    assert!(left.is_allowed(None, 0) && !left.is_allowed(None, 2));
    assert!(matches!(g.restricted(&["fly".into()]), Err(RestrictError::NotInGraph { skill, .. }) if skill == "fly"));
}

#[test]
fn the_toss_starts_in_catch_and_puts_down_only_after_it() {
    let s =
        ScenarioFile::load(std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenarios/toss.ron")).unwrap();
    let g = SkillGraph::of(&s.scenario);
    assert_eq!(g.names(), ["walk", "turn_left", "turn_right", "catch", "put_down"]);
    let (walk, catch, put_down) = (0, 3, 4);
    for k in 0..g.len() {
        assert_eq!(g.is_allowed(None, k), k == catch, "the ball is in the air at the start: {}", g.names()[k]);
        assert!(!g.is_allowed(Some(k), catch) || k == catch, "no second catch after {}", g.names()[k]);
    }
    assert!(
        g.is_allowed(Some(catch), walk) && g.is_allowed(Some(catch), put_down) && g.is_allowed(Some(walk), put_down)
    );
    // Dropping catch leaves no skill an episode could start with: refused, naming it.
    let err = g.restricted(&["walk".into(), "turn_left".into(), "turn_right".into()]).unwrap_err();
    assert!(matches!(&err, RestrictError::NoStart { starts, .. } if starts.iter().any(|s| s == "catch")), "{err:?}");
    assert!(err.to_string().contains("start skill") && err.to_string().contains("--chain"), "{err}");
    assert!(g.restricted(&["catch".into(), "put_down".into()]).is_ok());
}
