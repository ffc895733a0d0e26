//! Every shipped scene end to end with the template hand, as `ergohand grasp` runs it: the
//! part read and prepared, the placement search (or the given approach), the closing, the
//! squeeze, the evaluation and the rapier hold test (with the runners-up when the best does not
//! hold). The speed goal is 2 s a scene on two cores.

use criterion::{criterion_group, criterion_main, Criterion};
use ergohand::anatomy::Side;
use ergohand::grasp::scene::read_scene;
use ergohand::grasp::{run_scene, SkinnedHand};
use std::path::Path;

fn scenes_bench(c: &mut Criterion) {
    let hand = SkinnedHand::template(Side::Right).unwrap();
    let mut gr = c.benchmark_group("grasp_scene");
    gr.sample_size(10);
    for name in ["bottle", "drill", "phone", "mouse", "pen"] {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("scenes/{name}.toml"));
        let scene = read_scene(&path).unwrap();
        gr.bench_function(name, |b| {
            b.iter(|| run_scene(&scene, &hand).unwrap().report.holds)
        });
    }
    gr.finish();
}

criterion_group!(benches, scenes_bench);
criterion_main!(benches);
