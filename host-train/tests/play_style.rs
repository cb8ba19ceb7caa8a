//! `hexapod play` on an AMP checkpoint writes the discriminator's score and the style reward
//! of every step to `trajectory.csv`, the reward being the paper's `max(0, 1 - 0.25 (d - 1)^2)`
//! of the score; a checkpoint without a discriminator writes neither column.

use host_train::cli::play::{run, PlayArgs};
use std::path::Path;

fn play(checkpoint: &str, name: &str) -> (Vec<String>, Vec<Vec<f64>>) {
    let out = std::env::temp_dir().join(format!("hexapod-play-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&out);
    run(PlayArgs {
        checkpoint: Path::new(env!("CARGO_MANIFEST_DIR")).join(checkpoint),
        steps: 60,
        command: [0.3, 0.0, 0.0],
        out: Some(out.clone()),
        env: None,
        no_replay: true,
        tile: None,
        level: None,
        rerun: false,
    })
    .unwrap();
    let text = std::fs::read_to_string(out.join("trajectory.csv")).unwrap();
    std::fs::remove_dir_all(&out).ok();
    let mut lines = text.lines();
    let header: Vec<String> = lines
        .next()
        .unwrap()
        .split(',')
        .map(str::to_owned)
        .collect();
    let rows = lines
        .map(|l| l.split(',').map(|x| x.parse::<f64>().unwrap()).collect())
        .collect();
    (header, rows)
}

fn column(header: &[String], name: &str) -> Option<usize> {
    header.iter().position(|h| h == name)
}

#[test]
fn play_writes_the_style_reward_of_each_step() {
    let (header, rows) = play("../assets/policies/flat-amp-track", "amp");
    let d = column(&header, "d_score").expect("an AMP checkpoint has a d_score column");
    let r = column(&header, "style_reward").expect("and a style_reward column");
    assert_eq!(rows.len(), 60);
    let scores: Vec<f64> = rows.iter().map(|row| row[d]).collect();
    for (row, &score) in rows.iter().zip(&scores) {
        let expected = (1.0 - 0.25 * (score - 1.0).powi(2)).max(0.0);
        assert!(
            (row[r] - expected).abs() < 1e-5,
            "d {score}: style {} against {expected}",
            row[r]
        );
        assert!((0.0..=1.0).contains(&row[r]));
    }
    let (lo, hi) = scores
        .iter()
        .fold((f64::MAX, f64::MIN), |(lo, hi), &s| (lo.min(s), hi.max(s)));
    assert!(hi - lo > 1e-3, "the score follows the gait: {lo}..{hi}");
}

#[test]
fn play_without_a_discriminator_writes_no_style_columns() {
    // RMA's deployed student: trained on r_g + r_l, no style reward (`style = false`).
    let (header, rows) = play(
        "../assets/reports/comparison-terrain/comparison-rma-s1/comparison-rma-s1-adapted",
        "no-amp",
    );
    assert_eq!(rows.len(), 60);
    assert!(column(&header, "clearance_m_lr").is_some());
    assert!(column(&header, "d_score").is_none() && column(&header, "style_reward").is_none());
}
