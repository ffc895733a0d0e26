//! Reading mutated C3D files never asks for much more memory than the file holds.
//!
//! Its own test binary because it installs a counting global allocator: the largest single
//! allocation requested while `read_c3d_bytes` runs on each mutant is compared with the mutant's
//! length. (The reader sizes its tracks and parameter copies from header and parameter counts;
//! an unchecked count would show here as a request of megabytes to gigabytes for a file of a few
//! kilobytes.)

use ergohand::geometry::Point;
use ergohand::mocap::c3d::{read_c3d_bytes, write_c3d};
use ergohand::mocap::trajectories::Trajectories;
use std::alloc::{GlobalAlloc, Layout, System};
use std::collections::BTreeMap;
use std::path::Path;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};

struct Counting;

static ARMED: AtomicBool = AtomicBool::new(false);
static LARGEST: AtomicUsize = AtomicUsize::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if ARMED.load(Ordering::Relaxed) {
            LARGEST.fetch_max(layout.size(), Ordering::Relaxed);
        }
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if ARMED.load(Ordering::Relaxed) {
            LARGEST.fetch_max(new_size, Ordering::Relaxed);
        }
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// xorshift64*: a fixed, dependency-free stream of mutations.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[test]
fn mutants_allocate_in_proportion_to_their_size() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("v.c3d");
    let labels = ["PALM_1", "PALM_2", "PALM_3", "I_MID_1"];
    let positions = (0..labels.len())
        .map(|m| {
            (0..60)
                .map(|f| ((f + m) % 5 != 0).then(|| Point::new(f as f64, m as f64, 1.5)))
                .collect()
        })
        .collect();
    let t = Trajectories::new(
        100.0,
        labels.iter().map(|s| s.to_string()).collect(),
        positions,
        "v.c3d",
    )
    .unwrap();
    write_c3d(&path, &t).unwrap();
    let good = std::fs::read(&path).unwrap();
    let map = BTreeMap::new();
    let name = Path::new("m.c3d");
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    let mut worst = (0usize, 0usize);
    for round in 0..3000 {
        let mut b = good.clone();
        match round % 3 {
            // Header and parameter section, where the counts live.
            0 => {
                for _ in 0..1 + rng.below(6) {
                    let at = rng.below(1536);
                    b[at] = rng.next() as u8;
                }
            }
            // Whole 16-bit words of the header set to anything.
            1 => {
                for _ in 0..1 + rng.below(3) {
                    let w = rng.below(12);
                    b[2 * w..2 * w + 2].copy_from_slice(&(rng.next() as u16).to_le_bytes());
                }
            }
            // Truncation after a few edits anywhere.
            _ => {
                for _ in 0..rng.below(8) {
                    let at = rng.below(b.len());
                    b[at] = rng.next() as u8;
                }
                b.truncate(rng.below(good.len() + 1));
            }
        }
        LARGEST.store(0, Ordering::Relaxed);
        ARMED.store(true, Ordering::Relaxed);
        let _ = read_c3d_bytes(&b, &map, name);
        ARMED.store(false, Ordering::Relaxed);
        let largest = LARGEST.load(Ordering::Relaxed);
        if largest > worst.0 {
            worst = (largest, b.len());
        }
        assert!(
            largest <= 4 * b.len() + 65_536,
            "round {round}: a {}-byte mutant asked for {largest} bytes at once",
            b.len()
        );
    }
    // The reads did allocate (the tracks exist), so the bound was exercised.
    assert!(worst.0 > 0);
}
