//! `repertoire bench ppo` runs end to end on the default scene and reports its table.

use std::process::Command;

#[test]
fn bench_ppo_reports_samples_per_second_beside_the_physics_ceiling() {
    let out = Command::new(env!("CARGO_BIN_EXE_repertoire"))
        .args(["bench", "ppo", "--envs", "4", "--steps", "8", "--iters", "1", "--hidden", "16"])
        .args(["--epochs", "1", "--minibatches", "2", "--physics-steps", "400", "--threads", "2,1"])
        .output()
        .expect("run repertoire");
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "exit {:?}\n{text}\n{}", out.status, String::from_utf8_lossy(&out.stderr));
    let rate = |label: &str| -> f64 {
        let line = text.lines().find(|l| l.starts_with(label)).unwrap_or_else(|| panic!("no `{label}` row in\n{text}"));
        line.split('|').nth(2).and_then(|c| c.trim().parse().ok()).unwrap_or_else(|| panic!("no rate in {line}"))
    };
    let ppo = rate("| PPO end to end");
    let raw = rate("| raw mj_step ceiling");
    assert!(ppo > 0.0 && raw > 0.0, "{text}");
    assert!(text.contains("physics share of PPO wall time"), "{text}");
    // The scaling table: each pool size against one thread (measured second here).
    assert!(text.contains("| threads | PPO samples/s | vs 1 thread |"), "{text}");
    let one = text.lines().find(|l| l.starts_with("| 1 |")).unwrap_or_else(|| panic!("{text}"));
    assert!(one.ends_with("| 1.00× |"), "{one}");
    assert!(text.lines().any(|l| l.starts_with("| 2 |") && l.ends_with("× |")), "{text}");
}
