//! The accuracy regression check, on the CI subset of the validation suite: the subjects
//! of `[ci.subject.*]` in `validation/thresholds.toml` are simulated from `validation/suite.toml`
//! with the subset's shorter trials, reconstructed and validated as `ergohand validate` does;
//! the test fails naming the subject and the figure of every figure worse than its threshold.
//! `ergohand validate --suite validation/` checks the whole suite against the same file.

use ergohand::cli;
use ergohand::validate::thresholds::{check, describe, Figures, Thresholds, FILE};
use std::path::Path;

#[test]
fn ci_subset_meets_the_accuracy_thresholds() {
    let vdir = Path::new(env!("CARGO_MANIFEST_DIR")).join("validation");
    let thresholds = Thresholds::load(&vdir.join(FILE)).unwrap();
    let suite = ergohand::synth::suite::read_suite(&vdir.join("suite.toml")).unwrap();
    let ci = &thresholds.ci;
    assert!(!ci.subject.is_empty(), "the CI subset is empty");
    let tmp = tempfile::tempdir().unwrap();
    let mut regressions = Vec::new();
    let mut measured = Vec::new();
    for (name, limits) in &ci.subject {
        let (_, suite_opts) = suite
            .iter()
            .find(|(n, _)| n == name)
            .unwrap_or_else(|| panic!("CI subject {name} is not in validation/suite.toml"));
        let mut opts = suite_opts.clone();
        opts.duration_s = Some(ci.duration_s);
        if let Some(v) = ci.voxel_mm {
            opts.voxel_mm = v;
        }
        let sdir = tmp.path().join(name);
        let model = sdir.join("out");
        cli::synth(&opts, &sdir, false).unwrap();
        cli::reconstruct(&sdir, &model).unwrap();
        let v = cli::validate(&sdir, &model, &model.join("report")).unwrap();
        let (link, surface) = v.against_references(&sdir).unwrap();
        let figures = Figures::measure(link, surface, &v.dimensions, &model).unwrap();
        regressions.extend(check(name, &figures, limits));
        measured.push(format!("{name}: {:?}", figures.0));
    }
    // The figures, for whoever updates the thresholds (shown with --nocapture or on failure).
    eprintln!("{}", measured.join("\n"));
    assert!(
        regressions.is_empty(),
        "accuracy regressions against validation/{FILE} [ci]: {}\nmeasured:\n{}",
        describe(&regressions),
        measured.join("\n")
    );
}
