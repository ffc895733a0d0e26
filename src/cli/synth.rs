//! `ergohand synth`: a simulated subject folder from the command's options.

use crate::anatomy::Side;
use crate::error::Result;
use crate::io::output_paths::{check_output_dir, Inputs};
use crate::synth::{self, Body, Posture, Preset, SynthOptions};
use std::path::Path;
use std::time::Instant;

/// Options of `ergohand synth` from its command-line values.
pub fn synth_options(
    seed: u64,
    preset: Preset,
    hand: Side,
    posture: Posture,
    body: Body,
    duration: Option<f64>,
    motion_s: Option<f64>,
) -> SynthOptions {
    SynthOptions {
        hand,
        posture,
        body,
        duration_s: duration,
        motion_s,
        ..SynthOptions::new(seed, preset)
    }
}

/// `--sex` and `--percentile` of `synth` as the options' percentile hand: only with the
/// procedural body (the template body's size is drawn), a percentile strictly between 0 and 100.
pub fn percentile_hand(
    body: Body,
    sex: Option<synth::procedural::Sex>,
    percentile: Option<f64>,
) -> Result<Option<(synth::procedural::Sex, f64)>> {
    let (Some(sex), Some(p)) = (sex, percentile) else {
        return Ok(None);
    };
    if body != Body::Procedural {
        return Err(crate::Error::invalid(
            "--percentile: a percentile hand needs --body procedural (the template body's size is drawn)",
        ));
    }
    if !(p > 0.0 && p < 100.0) {
        return Err(crate::Error::invalid(format!(
            "--percentile {p}: give a percentile between 0 and 100 (e.g. 5, 50, 95)"
        )));
    }
    Ok(Some((sex, p)))
}

/// `ergohand synth`: simulate a subject and write its folder.
pub fn synth(opts: &SynthOptions, out: &Path, force: bool) -> Result<()> {
    let t0 = Instant::now();
    check_output_dir(out, &[], "--out", &Inputs::default())?;
    synth::check_subject_dir(out, force)?;
    let spinner = super::progress(2, "synth");
    spinner.set_message("simulating");
    let s = synth::simulate(opts)?;
    spinner.inc(1);
    spinner.set_message("writing");
    synth::write_subject(out, &s, force)?;
    spinner.finish_and_clear();
    let frames: usize = s.trials.values().map(|t| t.n_frames()).sum();
    for (name, m) in &s.motions {
        let hidden = m
            .trajectories
            .positions
            .iter()
            .flatten()
            .filter(|p| p.is_none())
            .count();
        let cells = m.trajectories.positions.len() * m.trajectories.n_frames();
        log::info!(
            "synth: motion {name}: {} frames, {} markers, {:.1} % of samples hidden, {} label swap(s)",
            m.trajectories.n_frames(),
            m.trajectories.labels.len(),
            100.0 * hidden as f64 / cells.max(1) as f64,
            m.truth.label_swaps.len()
        );
    }
    log::info!(
        "synth: {} ({} hand, {} body, preset {}, posture {:?}) -> {}: {} trials, {} frames, reference surface {} faces, {:.1} s",
        s.subject.name,
        opts.hand,
        opts.body.name(),
        opts.preset.name(),
        opts.posture,
        out.display(),
        s.trials.len(),
        frames,
        s.reference.n_faces(),
        t0.elapsed().as_secs_f64()
    );
    Ok(())
}
