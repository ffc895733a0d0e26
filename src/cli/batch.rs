//! `ergohand batch SUBJECTS_DIR --out DIR [--jobs N]`: every subject folder of `SUBJECTS_DIR`
//! reconstructed as `ergohand reconstruct` would ([`super::reconstruct_with`]) into
//! `DIR/<subject folder name>/`, several at once, with one progress bar, a summary table and
//! skipping of subjects whose outputs were made from the very bytes of their inputs (the content
//! fingerprint `report.json` records, [`super::reconstruct_fingerprint`]) and are newer
//! than them.
//!
//! Concurrency, and why it is safe:
//! - **One pool of `jobs` threads.** `jobs` plain threads take subjects from a shared counter and
//!   run each inside [`rayon::ThreadPool::install`] of a single rayon pool of `jobs` threads. The
//!   stages' own `par_iter`s then run on that pool, so the batch never has more than `jobs`
//!   threads computing (no pool per subject, no oversubscription), and at most `jobs` subjects are
//!   in memory at a time: a thread that calls `install` from outside the pool blocks, whereas a
//!   rayon worker waiting inside a nested `par_iter` would steal and start further subjects.
//!   faer runs every sparse factorisation and solve with `Par::Seq`
//!   ([`crate::geometry::sparse_cholesky`]), so it adds no threads of its own.
//! - **The template's tetrahedral mesh cache** (`$ERGOHAND_CACHE`, [`crate::tet::cache`]) is
//!   filled once per hand before the subjects start, so parallel subjects only read it instead of
//!   each stuffing the template and writing the same cache file at once. Cache writes go through
//!   [`crate::io::atomic`], whose temporary names are unique per process *and* per write, so
//!   concurrent writers (threads, or processes on a cluster sharing the cache) never share one.
//! - **Outputs** are per subject (`DIR/<name>/`); the summary is written once, at the end.
//!
//! With tracking on ([`BatchOptions::track`]), every motion trial of every subject whose
//! reconstruction stands (made now or up to date) is then replayed as `ergohand track` would
//! ([`super::track_job`]) into `DIR/<name>/motions/<motion>/`, on the same pool. Motions are
//! tracked again on every run: a trial takes seconds, and its outputs depend on the model, the
//! scene and the trial, which a fingerprint of the subject's inputs alone would not cover.

use super::reconstruct::{reconstruct_fingerprint, reconstruct_job};
use super::track::track_job;
use super::Voice;
use crate::anatomy::Side;
use crate::error::{Error, Result};
use crate::io::atomic;
use crate::mocap::subject::{Subject, SUBJECT_FILE};
use crate::skin::pipeline::SkinOptions;
use rayon::prelude::*;
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Instant, SystemTime};

/// The files `ergohand reconstruct` writes into its output folder (spec section 3 and
/// [`super::reconstruct_with`]); a subject is up to date when all of them exist, are
/// newer than every input, and `report.json` records the inputs' current fingerprint.
pub const OUTPUTS: [&str; 7] = crate::io::output_paths::MODEL_FILES;

/// Threads per core at most: more only adds memory (each thread holds a subject) and switching.
pub(crate) const JOBS_PER_CORE: usize = 2;

/// The summary files written into the batch's output folder.
pub(crate) const SUMMARY_MD: &str = "batch-summary.md";
/// See [`SUMMARY_MD`].
pub(crate) const SUMMARY_JSON: &str = "batch-summary.json";

/// How a batch runs.
#[derive(Clone, Debug, Default)]
pub struct BatchOptions {
    /// Threads (subjects at once, and the threads they share); `None`: the available cores.
    pub jobs: Option<usize>,
    /// The skin options every subject is reconstructed with.
    pub skin: SkinOptions,
    /// The template folder every subject is reconstructed from (`None`: the generic hand).
    pub template: Option<PathBuf>,
    /// Track every motion trial of every subject, with these scenes (`None`: no tracking).
    pub track: Option<MotionScenes>,
}

/// The folder, under a subject's output folder, where its motions are tracked
/// (`DIR/<name>/motions/<motion>/`).
pub const MOTIONS_DIR: &str = "motions";

/// Which scene's part each motion handles, for tracking in a batch: a scene per motion name
/// (`grasp_bottle=scenes/bottle.toml`) and one for every other motion (a bare path). A motion
/// with neither is tracked without a part (no contacts).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MotionScenes {
    /// By motion name.
    pub by_motion: BTreeMap<String, PathBuf>,
    /// For the motions not named in `by_motion`.
    pub every: Option<PathBuf>,
}

impl MotionScenes {
    /// Parse `--scene` values: `MOTION=SCENE.toml` or `SCENE.toml`. Errors name the value: a
    /// motion given twice, two bare scenes, an empty name or path, a scene file that does not
    /// exist.
    pub fn parse<S: AsRef<str>>(values: &[S]) -> Result<MotionScenes> {
        let mut out = MotionScenes::default();
        for v in values {
            let v = v.as_ref();
            let (name, path) = match v.split_once('=') {
                Some((n, p)) => (Some(n.trim()), p.trim()),
                None => (None, v.trim()),
            };
            if path.is_empty() || name.is_some_and(str::is_empty) {
                return Err(Error::invalid(format!(
                    "--scene '{v}': give MOTION=SCENE.toml or SCENE.toml"
                )));
            }
            let path = PathBuf::from(path);
            if !path.is_file() {
                return Err(Error::input(
                    &path,
                    format!("not found (--scene '{v}'); give an existing scene file"),
                ));
            }
            let twice = match name {
                Some(n) => out.by_motion.insert(n.to_string(), path).is_some(),
                None => out.every.replace(path).is_some(),
            };
            if twice {
                return Err(Error::invalid(format!(
                    "--scene '{v}': a scene for {} is given twice",
                    name.map_or("every motion".to_string(), |n| format!("motion '{n}'"))
                )));
            }
        }
        Ok(out)
    }

    /// The scene of motion `name`.
    pub fn for_motion(&self, name: &str) -> Option<&Path> {
        self.by_motion
            .get(name)
            .or(self.every.as_ref())
            .map(PathBuf::as_path)
    }
}

/// What became of one motion of a subject.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct MotionOutcome {
    /// The motion's name (`[motions]` key; also its output folder's).
    pub motion: String,
    /// The scene its part came from, if any.
    pub scene: Option<PathBuf>,
    /// Frames in the trial (0 when it failed).
    pub frames: usize,
    /// Frames that could not be solved.
    pub unsolved: usize,
    /// Warnings of the tracking (see the motion's `motion.json`).
    pub warnings: usize,
    /// Wall time, s.
    pub seconds: f64,
    /// The one-line error of a failed motion.
    pub error: Option<String>,
}

/// What became of one subject.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Status {
    /// Reconstructed now.
    Ok,
    /// Reconstruction failed; the error is in [`SubjectOutcome::error`].
    Failed,
    /// Skipped: every output was newer than every input.
    SkippedUpToDate,
}

impl Status {
    /// The word used in the tables.
    pub fn word(self) -> &'static str {
        match self {
            Status::Ok => "ok",
            Status::Failed => "failed",
            Status::SkippedUpToDate => "skipped-up-to-date",
        }
    }
}

/// Key figures of a subject's `report.json` (absent figures are `None`).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct KeyFigures {
    /// Largest landmark residual of the skin fit (a marker's distance to the written skin
    /// minus its offset, absolute), mm.
    pub landmark_residual_max_mm: Option<f64>,
    /// Largest |caliper pair residual| of the skin fit (its template vertex pairs), mm.
    pub caliper_pair_residual_max_mm: Option<f64>,
    /// Skin faces turned over by the fit.
    pub inverted_faces: Option<u64>,
    /// Inverted tetrahedra of the subject's mesh.
    pub inverted_tets: Option<u64>,
    /// Smallest dihedral angle of the subject's tetrahedral mesh, degrees.
    pub min_dihedral_deg: Option<f64>,
    /// Warnings of the link model and the skin fit.
    pub warnings: Option<usize>,
}

impl KeyFigures {
    /// The figures of `OUT/report.json`; `None` when it cannot be read as JSON.
    pub fn read(report: &Path) -> Option<KeyFigures> {
        let text = std::fs::read_to_string(report).ok()?;
        let v: serde_json::Value = serde_json::from_str(&text).ok()?;
        let max_abs = |m: &serde_json::Value| {
            m.as_object().map(|o| {
                o.values()
                    .filter_map(serde_json::Value::as_f64)
                    .fold(0.0_f64, |a, x| a.max(x.abs()))
            })
        };
        Some(KeyFigures {
            landmark_residual_max_mm: max_abs(&v["skin"]["landmark_residuals_mm"]),
            caliper_pair_residual_max_mm: max_abs(&v["skin"]["caliper_pair_residuals_mm"]),
            inverted_faces: v["skin"]["inverted_faces"].as_u64(),
            inverted_tets: v["tet"]["inverted"].as_u64(),
            min_dihedral_deg: v["tet"]["subject_quality"]["min_dihedral_deg"]["min"].as_f64(),
            warnings: v["warnings"].as_array().map(Vec::len),
        })
    }
}

/// One row of the summary.
#[derive(Clone, Debug, Serialize)]
pub struct SubjectOutcome {
    /// The subject folder's name (also its output folder's).
    pub subject: String,
    /// What happened.
    pub status: Status,
    /// Wall time of its reconstruction in this run, s (0 when skipped).
    pub seconds: f64,
    /// The one-line error of a failed subject.
    pub error: Option<String>,
    /// Figures of its `report.json` (this run's, or the earlier one of a skipped subject).
    pub figures: Option<KeyFigures>,
    /// Its motions, when tracking (in name order).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub motions: Vec<MotionOutcome>,
}

/// The whole batch.
#[derive(Clone, Debug, Serialize)]
pub struct BatchSummary {
    /// `SUBJECTS_DIR`.
    pub subjects_dir: PathBuf,
    /// `DIR`.
    pub out: PathBuf,
    /// Threads used.
    pub jobs: usize,
    /// Wall time of the batch, s.
    pub seconds: f64,
    /// One row per subject folder, by name.
    pub subjects: Vec<SubjectOutcome>,
}

impl BatchSummary {
    /// Subjects with `status`.
    pub fn count(&self, status: Status) -> usize {
        self.subjects.iter().filter(|s| s.status == status).count()
    }

    /// The failed subjects' names.
    pub fn failed(&self) -> Vec<&str> {
        self.subjects
            .iter()
            .filter(|s| s.status == Status::Failed)
            .map(|s| s.subject.as_str())
            .collect()
    }

    /// The failed motions, as `subject/motion`.
    pub fn failed_motions(&self) -> Vec<String> {
        self.subjects
            .iter()
            .flat_map(|s| {
                s.motions
                    .iter()
                    .filter(|m| m.error.is_some())
                    .map(move |m| format!("{}/{}", s.subject, m.motion))
            })
            .collect()
    }

    /// The summary as a markdown table (also what is printed on stderr).
    pub(crate) fn to_markdown(&self) -> String {
        let f = |x: Option<f64>, p: usize| x.map_or("-".into(), |x| format!("{x:.p$}"));
        let n = |x: Option<u64>| x.map_or("-".into(), |x| x.to_string());
        let mut md = format!(
            "# Batch summary\n\n`ergohand batch {}` -> `{}`: {} subjects, {} ok, {} failed, {} skipped (up to date); {} jobs, {:.1} s.\n\n",
            self.subjects_dir.display(),
            self.out.display(),
            self.subjects.len(),
            self.count(Status::Ok),
            self.count(Status::Failed),
            self.count(Status::SkippedUpToDate),
            self.jobs,
            self.seconds
        );
        md.push_str("| subject | status | time (s) | landmark residual max (mm) | caliper pair residual max (mm) | inverted skin faces | inverted tets | min dihedral (deg) | warnings | error |\n|---|---|---|---|---|---|---|---|---|---|\n");
        for s in &self.subjects {
            let k = s.figures.clone().unwrap_or_default();
            let time = if s.status == Status::SkippedUpToDate {
                "-".into()
            } else {
                format!("{:.1}", s.seconds)
            };
            md.push_str(&format!(
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
                s.subject,
                s.status.word(),
                time,
                f(k.landmark_residual_max_mm, 3),
                f(k.caliper_pair_residual_max_mm, 3),
                n(k.inverted_faces),
                n(k.inverted_tets),
                f(k.min_dihedral_deg, 1),
                k.warnings.map_or("-".into(), |w| w.to_string()),
                s.error.as_deref().unwrap_or("").replace('|', "\\|"),
            ));
        }
        if self.subjects.iter().any(|s| !s.motions.is_empty()) {
            md.push_str("\n## Motions\n\nTracked into `<subject>/motions/<motion>/` (motion.json, motion.glb and the trial's pictures and page).\n\n| subject | motion | scene | frames | solved | warnings | time (s) | error |\n|---|---|---|---|---|---|---|---|\n");
            for s in &self.subjects {
                for m in &s.motions {
                    md.push_str(&format!(
                        "| {} | {} | {} | {} | {} | {} | {:.1} | {} |\n",
                        s.subject,
                        m.motion,
                        m.scene
                            .as_ref()
                            .map_or("-".into(), |p| p.display().to_string()),
                        m.frames,
                        m.frames - m.unsolved.min(m.frames),
                        m.warnings,
                        m.seconds,
                        m.error.as_deref().unwrap_or("").replace('|', "\\|"),
                    ));
                }
            }
        }
        md
    }
}

/// The subject folders of `dir`: its sub-folders holding `subject.toml`, sorted by name, as
/// `(name, path)`. Errors when `dir` cannot be read or holds no subject folder.
pub(crate) fn discover(dir: &Path) -> Result<Vec<(String, PathBuf)>> {
    let entries = std::fs::read_dir(dir).map_err(|e| Error::io(dir, e))?;
    let mut out = Vec::new();
    for e in entries {
        let e = e.map_err(|e| Error::io(dir, e))?;
        let path = e.path();
        if path.is_dir() && path.join(SUBJECT_FILE).is_file() {
            out.push((e.file_name().to_string_lossy().into_owned(), path));
        }
    }
    if out.is_empty() {
        let hint = if dir.join(SUBJECT_FILE).is_file() {
            " (this is a subject folder itself: use `ergohand reconstruct` or give its parent)"
        } else {
            ""
        };
        return Err(Error::input(
            dir,
            format!("no subject folders (sub-folders holding {SUBJECT_FILE}){hint}"),
        ));
    }
    out.sort();
    Ok(out)
}

/// The inputs of a subject: its `subject.toml` and every trial file it names.
pub fn inputs(subject_dir: &Path) -> Result<Vec<PathBuf>> {
    let s = Subject::load(subject_dir)?;
    let mut v = vec![s.toml_path()];
    v.extend(s.trials.values().map(|p| s.dir.join(p)));
    Ok(v)
}

/// Were `out`'s [`OUTPUTS`] made from the inputs of `subject_dir` as they are now, with
/// `opts`? All must exist and be newer than every input, and `report.json`'s `inputs_fnv1a`
/// must equal the inputs' content fingerprint now ([`super::reconstruct_fingerprint`]),
/// so a subject folder replaced with preserved timestamps is redone. `false` whenever anything
/// cannot be read (a missing output, an unreadable `subject.toml`, a missing trial), so such a
/// subject is run and reports its own error.
pub(crate) fn up_to_date(
    subject_dir: &Path,
    out: &Path,
    opts: &SkinOptions,
    template: Option<&Path>,
) -> bool {
    if !newer_than_inputs(subject_dir, out) {
        return false;
    }
    let recorded = std::fs::read_to_string(out.join("report.json"))
        .ok()
        .and_then(|t| serde_json::from_str::<serde_json::Value>(&t).ok())
        .and_then(|v| v["inputs_fnv1a"].as_str().map(str::to_string));
    let now = Subject::load(subject_dir)
        .and_then(|s| reconstruct_fingerprint(&s, opts, template))
        .ok();
    matches!((recorded, now), (Some(r), Some(n)) if r == n)
}

/// Are all of `out`'s [`OUTPUTS`] newer than every input of `subject_dir`?
fn newer_than_inputs(subject_dir: &Path, out: &Path) -> bool {
    let mtime = |p: &Path| -> Option<SystemTime> { std::fs::metadata(p).ok()?.modified().ok() };
    let newest_input = match inputs(subject_dir) {
        Ok(v) => v.iter().map(|p| mtime(p)).collect::<Option<Vec<_>>>(),
        Err(_) => None,
    }
    .and_then(|v| v.into_iter().max());
    let oldest_output = OUTPUTS
        .iter()
        .map(|f| mtime(&out.join(f)))
        .collect::<Option<Vec<_>>>()
        .and_then(|v| v.into_iter().min());
    match (newest_input, oldest_output) {
        (Some(i), Some(o)) => o > i,
        _ => false,
    }
}

/// Run the batch and write `DIR/batch-summary.md` and `.json`. Failing subjects are in the
/// summary (status `failed`, their one-line error); the `Err` case is only for the batch itself
/// (no subjects, bad `--jobs`, an unwritable `DIR`). See [`batch`] for the exit status.
pub fn run(subjects_dir: &Path, out: &Path, opts: &BatchOptions) -> Result<BatchSummary> {
    let t0 = Instant::now();
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    if opts.jobs == Some(0) {
        return Err(Error::invalid("--jobs 0: give at least 1 thread"));
    }
    let subjects = discover(subjects_dir)?;
    crate::io::output_paths::check_output_dir(
        out,
        &[SUMMARY_MD, SUMMARY_JSON],
        "--out",
        &crate::io::output_paths::Inputs::files(subjects.iter().map(|s| s.1.join(SUBJECT_FILE))),
    )?;
    std::fs::create_dir_all(out).map_err(|e| Error::io(out, e))?;
    let removed = remove_stale_temporaries(out, &subjects);
    if !removed.is_empty() {
        log::info!(
            "batch: removed {} temporary files left by an interrupted run (e.g. {})",
            removed.len(),
            removed[0].display()
        );
    }

    let mut rows: Vec<Option<SubjectOutcome>> = vec![None; subjects.len()];
    let mut todo = Vec::new();
    for (i, (name, dir)) in subjects.iter().enumerate() {
        let sout = out.join(name);
        if up_to_date(dir, &sout, &opts.skin, opts.template.as_deref()) {
            rows[i] = Some(SubjectOutcome {
                subject: name.clone(),
                status: Status::SkippedUpToDate,
                seconds: 0.0,
                error: None,
                figures: KeyFigures::read(&sout.join("report.json")),
                motions: Vec::new(),
            });
        } else {
            todo.push(i);
        }
    }
    let skipped = subjects.len() - todo.len();
    if skipped > 0 {
        let names: Vec<&str> = rows.iter().flatten().map(|r| r.subject.as_str()).collect();
        let list = if names.len() <= 10 {
            format!(": {}", names.join(", "))
        } else {
            String::new()
        };
        log::info!(
            "batch: {skipped} of {} subjects up to date (outputs made from the same subject.toml, trials and options), skipped{list}",
            subjects.len()
        );
    }
    let (jobs, clamped) = clamp_jobs(opts.jobs, cores, todo.len());
    if let (Some(asked), false) = (clamped, todo.is_empty()) {
        log::warn!(
            "batch: --jobs {asked} lowered to {jobs} ({JOBS_PER_CORE} per core on {cores} cores, \
             at most one per subject to do)"
        );
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(jobs)
        .thread_name(|i| format!("ergohand-batch-{i}"))
        .build()
        .map_err(|e| Error::invalid(format!("--jobs {jobs}: cannot start the threads: {e}")))?;
    if !todo.is_empty() {
        log::info!(
            "batch: reconstructing {} subjects with {jobs} threads into {}",
            todo.len(),
            out.display()
        );
    }

    // The template's tet stage (cached mesh, binding, factorisation) once per hand, shared by
    // every subject of that hand, before subjects race to build the cache. A hand whose
    // preparation fails leaves its subjects to prepare (and report) it themselves.
    // Per subject to do, its hand (None when subject.toml does not load: that subject's own
    // run reports why).
    let hands: Vec<Option<Side>> = todo
        .iter()
        .map(|&i| Subject::load(&subjects[i].1).ok().map(|s| s.hand))
        .collect();
    let mut sides: Vec<Side> = hands.iter().flatten().copied().collect();
    sides.sort_by_key(|s| *s == Side::Left);
    sides.dedup();
    let prepared: Vec<crate::tet::TemplateTet> = pool.install(|| {
        sides
            .iter()
            .filter_map(|&side| {
                let t = crate::template::load_template_from(opts.template.as_deref(), side).ok()?;
                crate::tet::TemplateTet::prepare(&t, None).ok()
            })
            .collect()
    });
    let prepared_for = |k: usize| {
        let hand = hands[k]?;
        prepared.iter().find(|p| p.side == hand)
    };

    let pb = super::progress(todo.len() as u64, "batch");
    let next = AtomicUsize::new(0);
    let done = Mutex::new(Vec::new());
    std::thread::scope(|scope| {
        for _ in 0..jobs.min(todo.len()) {
            scope.spawn(|| loop {
                let k = next.fetch_add(1, Ordering::Relaxed);
                let Some(&i) = todo.get(k) else { break };
                let (name, dir) = &subjects[i];
                let sout = out.join(name);
                let t = Instant::now();
                let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                    pool.install(|| {
                        let shared = prepared_for(k);
                        reconstruct_job(
                            dir,
                            &sout,
                            &opts.skin,
                            opts.template.as_deref(),
                            shared,
                            Voice::Nested,
                        )
                    })
                }));
                let seconds = t.elapsed().as_secs_f64();
                let error = match result {
                    Ok(Ok(_)) => None,
                    Ok(Err(e)) => Some(e.to_string()),
                    Err(p) => Some(format!(
                        "{}: internal error (panic: {}); please report it",
                        dir.display(),
                        p.downcast_ref::<&str>()
                            .map(|s| s.to_string())
                            .or_else(|| p.downcast_ref::<String>().cloned())
                            .unwrap_or_default()
                    )),
                };
                if let Some(e) = &error {
                    // Errors are shown even with --quiet, above the bar.
                    pb.suspend(|| log::error!("subject {name} failed: {e}"));
                }
                let row = SubjectOutcome {
                    subject: name.clone(),
                    status: if error.is_some() {
                        Status::Failed
                    } else {
                        Status::Ok
                    },
                    seconds,
                    figures: if error.is_none() {
                        KeyFigures::read(&sout.join("report.json"))
                    } else {
                        None
                    },
                    error,
                    motions: Vec::new(),
                };
                pb.set_message(name.clone());
                pb.inc(1);
                done.lock()
                    .unwrap_or_else(|p| p.into_inner())
                    .push((i, row));
            });
        }
    });
    pb.finish_and_clear();
    for (i, row) in done.into_inner().unwrap_or_else(|p| p.into_inner()) {
        rows[i] = Some(row);
    }
    if let Some(scenes) = &opts.track {
        track_motions(&subjects, out, scenes, &mut rows, &pool);
    }
    let summary = BatchSummary {
        subjects_dir: subjects_dir.to_path_buf(),
        out: out.to_path_buf(),
        jobs,
        seconds: t0.elapsed().as_secs_f64(),
        subjects: rows.into_iter().flatten().collect(),
    };
    let md = summary.to_markdown();
    atomic::write_bytes_atomic(&out.join(SUMMARY_MD), md.as_bytes())?;
    let json = serde_json::to_string_pretty(&summary).expect("serialisable");
    atomic::write_bytes_atomic(&out.join(SUMMARY_JSON), json.as_bytes())?;
    log::info!("{}", md.trim_end());
    Ok(summary)
}

/// Track every motion of every subject whose row is not failed into
/// `out/<name>/motions/<motion>/` on `pool`, one motion per task, and put the outcomes in the
/// rows. A subject folder that no longer loads, or a motion name that is not a plain folder
/// name, gives a failed motion, never a failed batch.
fn track_motions(
    subjects: &[(String, PathBuf)],
    out: &Path,
    scenes: &MotionScenes,
    rows: &mut [Option<SubjectOutcome>],
    pool: &rayon::ThreadPool,
) {
    let mut tasks: Vec<(usize, String)> = Vec::new();
    for (i, (_, dir)) in subjects.iter().enumerate() {
        if rows[i].as_ref().is_some_and(|r| r.status != Status::Failed) {
            if let Ok(s) = Subject::load(dir) {
                tasks.extend(s.motions.keys().map(|m| (i, m.clone())));
            }
        }
    }
    if tasks.is_empty() {
        log::info!("batch: no motions to track ([motions] of subject.toml)");
        return;
    }
    log::info!("batch: tracking {} motions", tasks.len());
    let pb = super::progress(tasks.len() as u64, "track");
    let outcomes: Vec<(usize, MotionOutcome)> = pool.install(|| {
        tasks
            .par_iter()
            .map(|(i, motion)| {
                let (name, dir) = &subjects[*i];
                let model = out.join(name);
                let scene = scenes.for_motion(motion);
                let t = Instant::now();
                let result = if plain_folder_name(motion) {
                    let mout = model.join(MOTIONS_DIR).join(motion);
                    std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        track_job(dir, &model, motion, scene, None, &mout, Voice::Nested)
                    }))
                    .unwrap_or_else(|_| {
                        Err(Error::invalid(format!(
                            "{}: internal error while tracking {motion}; please report it",
                            dir.display()
                        )))
                    })
                } else {
                    Err(Error::input(
                        dir.join(SUBJECT_FILE),
                        format!(
                            "[motions] key '{motion}' is not a plain folder name, so it cannot \
                             name its output folder; rename it (letters, digits, '_', '-', '.')"
                        ),
                    ))
                };
                let seconds = t.elapsed().as_secs_f64();
                let outcome = match result {
                    Ok(s) => MotionOutcome {
                        motion: motion.clone(),
                        scene: scene.map(Path::to_path_buf),
                        frames: s.frames,
                        unsolved: s.unsolved,
                        warnings: s.warnings.len(),
                        seconds,
                        error: None,
                    },
                    Err(e) => {
                        pb.suspend(|| log::error!("subject {name}, motion {motion} failed: {e}"));
                        MotionOutcome {
                            motion: motion.clone(),
                            scene: scene.map(Path::to_path_buf),
                            frames: 0,
                            unsolved: 0,
                            warnings: 0,
                            seconds,
                            error: Some(e.to_string()),
                        }
                    }
                };
                pb.set_message(format!("{name}/{motion}"));
                pb.inc(1);
                (*i, outcome)
            })
            .collect()
    });
    pb.finish_and_clear();
    for (i, o) in outcomes {
        if let Some(r) = rows[i].as_mut() {
            r.motions.push(o);
        }
    }
}

/// Whether `name` can be used as a folder name as it is: not empty, not `.`/`..`, only
/// letters, digits, `_`, `-` and `.` (no separators, nothing a shell or another system reads
/// differently).
fn plain_folder_name(name: &str) -> bool {
    !name.is_empty()
        && name != "."
        && name != ".."
        && name
            .chars()
            .all(|c| c.is_ascii_alphanumeric() || matches!(c, '_' | '-' | '.'))
}

/// The threads to use: `asked` (default: the cores) at most [`JOBS_PER_CORE`] x `cores` and at
/// most `todo` (no idle threads), at least 1; and `asked` again when a request was lowered.
pub(crate) fn clamp_jobs(
    asked: Option<usize>,
    cores: usize,
    todo: usize,
) -> (usize, Option<usize>) {
    let want = asked.unwrap_or(cores).max(1);
    let cap = (JOBS_PER_CORE * cores.max(1)).min(todo).max(1);
    match asked {
        Some(n) if n > cap => (cap, Some(n)),
        _ => (want.min(cap), None),
    }
}

/// Remove the temporary files ([`crate::io::atomic`]'s hidden `.NAME.*.tmp`) that a killed run
/// left in `out` and in the output folders of `subjects`: a dead writer's, or any older than
/// [`crate::io::atomic::STALE_TEMPORARY_AFTER`] ([`crate::io::atomic::is_stale_temporary`]; a
/// live writer's may be another run's write in progress). Returns the files removed.
pub(crate) fn remove_stale_temporaries(out: &Path, subjects: &[(String, PathBuf)]) -> Vec<PathBuf> {
    // The batch folder, each subject's folder, and each of its tracked motions' folders.
    let motion_folders = |sub: PathBuf| {
        std::fs::read_dir(sub.join(MOTIONS_DIR))
            .into_iter()
            .flatten()
            .flatten()
            .map(|e| e.path())
            .filter(|p| p.is_dir())
            .chain(std::iter::once(sub))
            .collect::<Vec<_>>()
    };
    let folders = std::iter::once(out.to_path_buf())
        .chain(subjects.iter().flat_map(|s| motion_folders(out.join(&s.0))));
    let mut removed: Vec<PathBuf> = folders
        .flat_map(|dir| crate::io::atomic::stale_temporaries_in(&dir))
        .filter(|p| std::fs::remove_file(p).is_ok())
        .collect();
    removed.sort();
    removed
}

/// `ergohand batch`: [`run`], then an error naming the failed subjects (so the command exits
/// non-zero) when any failed.
pub fn batch(subjects_dir: &Path, out: &Path, opts: &BatchOptions) -> Result<BatchSummary> {
    let summary = run(subjects_dir, out, opts)?;
    let failed = summary.failed();
    let failed_motions = summary.failed_motions();
    if failed.is_empty() && failed_motions.is_empty() {
        return Ok(summary);
    }
    if failed.is_empty() {
        let names = first_ten(&failed_motions);
        return Err(Error::invalid(format!(
            "batch: {} motions could not be tracked ({names}); the subjects and other motions \
             are done, see {}",
            failed_motions.len(),
            out.join(SUMMARY_MD).display()
        )));
    }
    let names = first_ten(&failed);
    Err(Error::invalid(format!(
        "batch: {} of {} subjects failed ({names}); the others are done, see {}",
        failed.len(),
        summary.subjects.len(),
        out.join(SUMMARY_MD).display()
    )))
}

/// The first ten of `names` joined by commas, and how many more there are.
fn first_ten<S: AsRef<str>>(names: &[S]) -> String {
    let mut out = names
        .iter()
        .take(10)
        .map(AsRef::as_ref)
        .collect::<Vec<_>>()
        .join(", ");
    if names.len() > 10 {
        out.push_str(&format!(" and {} more", names.len() - 10));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A subject folder with a subject.toml naming one trial, and a complete output folder.
    fn fake(dir: &Path) -> (PathBuf, PathBuf) {
        let s = dir.join("S1");
        std::fs::create_dir_all(s.join("trials")).unwrap();
        std::fs::write(
            s.join(SUBJECT_FILE),
            "name = \"S1\"\nhand = \"right\"\nmarker_offset_mm = 4.0\n[trials]\nreference = \"trials/reference.c3d\"\n",
        )
        .unwrap();
        std::fs::write(s.join("trials/reference.c3d"), b"x").unwrap();
        let o = dir.join("out/S1");
        std::fs::create_dir_all(&o).unwrap();
        (s, o)
    }

    fn set_mtime(p: &Path, t: SystemTime) {
        std::fs::File::options()
            .write(true)
            .open(p)
            .unwrap()
            .set_modified(t)
            .unwrap();
    }

    #[test]
    fn up_to_date_needs_every_output_newer_than_every_input() {
        let d = tempfile::tempdir().unwrap();
        let (s, o) = fake(d.path());
        let t0 = SystemTime::now() - std::time::Duration::from_secs(100);
        let later = t0 + std::time::Duration::from_secs(50);
        set_mtime(&s.join(SUBJECT_FILE), t0);
        set_mtime(&s.join("trials/reference.c3d"), t0);
        let opts = SkinOptions::default();
        let up_to_date = |s: &Path, o: &Path| up_to_date(s, o, &opts, None);
        // No outputs yet.
        assert!(!up_to_date(&s, &o));
        let fingerprint =
            reconstruct_fingerprint(&Subject::load(&s).unwrap(), &opts, None).unwrap();
        for f in OUTPUTS {
            let text = if f == "report.json" {
                format!("{{\"inputs_fnv1a\": \"{fingerprint}\"}}")
            } else {
                "o".into()
            };
            std::fs::write(o.join(f), text).unwrap();
            set_mtime(&o.join(f), later);
        }
        assert!(up_to_date(&s, &o));
        // A trial newer than one output: redo.
        set_mtime(&s.join("trials/reference.c3d"), later);
        assert!(!up_to_date(&s, &o));
        set_mtime(&s.join("trials/reference.c3d"), t0);
        // One output older than the subject.toml: redo.
        set_mtime(&o.join("tet.msh"), t0 - std::time::Duration::from_secs(1));
        assert!(!up_to_date(&s, &o));
        set_mtime(&o.join("tet.msh"), later);
        // A missing output or a missing trial: redo.
        std::fs::remove_file(o.join("hand.glb")).unwrap();
        assert!(!up_to_date(&s, &o));
        std::fs::write(o.join("hand.glb"), b"o").unwrap();
        set_mtime(&o.join("hand.glb"), later);
        assert!(up_to_date(&s, &o));
        // Same times, other content (a folder replaced with `cp -p`): redo.
        std::fs::write(s.join("trials/reference.c3d"), b"y").unwrap();
        set_mtime(&s.join("trials/reference.c3d"), t0);
        assert!(!up_to_date(&s, &o));
        // Other options: redo.
        std::fs::write(s.join("trials/reference.c3d"), b"x").unwrap();
        set_mtime(&s.join("trials/reference.c3d"), t0);
        assert!(up_to_date(&s, &o));
        let full = SkinOptions {
            centre_weight: 0.5,
            ..SkinOptions::default()
        };
        assert!(!super::up_to_date(&s, &o, &full, None));
        // Another template: redo; the same template folder with other content: redo again.
        let t = d.path().join("T");
        std::fs::create_dir(&t).unwrap();
        std::fs::write(t.join("right.glb"), b"a").unwrap();
        std::fs::write(t.join("left.glb"), b"a").unwrap();
        assert!(!super::up_to_date(&s, &o, &opts, Some(&t)));
        let subject = Subject::load(&s).unwrap();
        let with_t = reconstruct_fingerprint(&subject, &opts, Some(&t)).unwrap();
        std::fs::write(t.join("right.glb"), b"b").unwrap();
        std::fs::write(t.join("left.glb"), b"b").unwrap();
        assert_ne!(
            with_t,
            reconstruct_fingerprint(&subject, &opts, Some(&t)).unwrap()
        );
        std::fs::remove_file(s.join("trials/reference.c3d")).unwrap();
        assert!(!up_to_date(&s, &o));
    }

    #[test]
    fn jobs_are_clamped() {
        assert_eq!(clamp_jobs(Some(100_000), 2, 3), (3, Some(100_000)));
        assert_eq!(clamp_jobs(Some(100_000), 2, 50), (4, Some(100_000)));
        assert_eq!(clamp_jobs(Some(2), 2, 50), (2, None));
        assert_eq!(clamp_jobs(None, 8, 3), (3, None));
        assert_eq!(clamp_jobs(Some(3), 2, 0), (1, Some(3)));
    }

    #[test]
    fn stale_temporaries_are_removed_fresh_ones_kept() {
        let d = tempfile::tempdir().unwrap();
        let out = d.path();
        std::fs::create_dir_all(out.join("S1")).unwrap();
        let stale = out.join("S1/.tet.vtk.123.0.456.tmp");
        let fresh = out.join("S1/.skin.obj.124.0.789.tmp");
        let other = out.join("S1/notes.tmp");
        for p in [&stale, &fresh, &other] {
            std::fs::write(p, b"half").unwrap();
        }
        set_mtime(
            &stale,
            SystemTime::now() - 2 * crate::io::atomic::STALE_TEMPORARY_AFTER,
        );
        set_mtime(
            &other,
            SystemTime::now() - 2 * crate::io::atomic::STALE_TEMPORARY_AFTER,
        );
        let removed = remove_stale_temporaries(out, &[("S1".into(), out.join("S1"))]);
        assert_eq!(removed, vec![stale.clone()]);
        assert!(!stale.exists() && fresh.exists() && other.exists());
    }

    #[test]
    fn discover_lists_subject_folders_only() {
        let d = tempfile::tempdir().unwrap();
        fake(d.path());
        std::fs::create_dir_all(d.path().join("notes")).unwrap();
        std::fs::write(d.path().join("readme.txt"), b"x").unwrap();
        let found = discover(d.path()).unwrap();
        assert_eq!(found.len(), 1);
        assert_eq!(found[0].0, "S1");
        let e = discover(&d.path().join("notes")).unwrap_err().to_string();
        assert!(e.contains("notes") && e.contains(SUBJECT_FILE), "{e}");
        let e = discover(&d.path().join("S1")).unwrap_err().to_string();
        assert!(e.contains("reconstruct"), "{e}");
    }

    #[test]
    fn key_figures_come_from_report_json() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("report.json");
        std::fs::write(
            &p,
            r#"{"warnings": ["a", "b"], "skin": {"landmark_residuals_mm": {"X": 0.02, "Y": 0.4},
               "caliper_pair_residuals_mm": {"A": -0.3, "B": 0.1}, "inverted_faces": 0},
               "tet": {"inverted": 1, "subject_quality": {"min_dihedral_deg": {"min": 5.5}}}}"#,
        )
        .unwrap();
        let k = KeyFigures::read(&p).unwrap();
        assert_eq!(k.landmark_residual_max_mm, Some(0.4));
        assert_eq!(k.caliper_pair_residual_max_mm, Some(0.3));
        assert_eq!(k.inverted_faces, Some(0));
        assert_eq!(k.inverted_tets, Some(1));
        assert_eq!(k.min_dihedral_deg, Some(5.5));
        assert_eq!(k.warnings, Some(2));
        std::fs::write(&p, b"{").unwrap();
        assert!(KeyFigures::read(&p).is_none());
    }
}
