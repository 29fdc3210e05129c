//! Every input `cargo xtask fuzz` ever found failing (`tests/fuzz-regressions/<target>/`:
//! panics, aborts, allocations past the cap, hangs) is replayed here, so CI guards the
//! regressions without fuzzing. The replay runs in a child process under the fuzzer's
//! address-space cap and a time limit: an input that aborts, allocates past the cap or hangs
//! fails this test as it failed the fuzzer.

use std::time::{Duration, Instant};

use golden_tests::child::in_child;
use golden_tests::fuzz::{self, Context, Outcome};
use golden_tests::hostile;

#[test]
fn every_saved_fuzz_finding_is_refused_or_loads_without_a_panic() {
    in_child(
        "every_saved_fuzz_finding_is_refused_or_loads_without_a_panic",
        3 << 30,
        Duration::from_secs(300),
        || {
            let dir = hostile::scratch_dir("replay");
            let ctx = Context::new(fuzz::fuzz_budget(), &dir);
            let mut replayed = 0;
            for target in fuzz::targets() {
                for file in fuzz::regressions(&target) {
                    let bytes = std::fs::read(&file).unwrap();
                    let start = Instant::now();
                    let outcome = fuzz::run(&target, &bytes, &ctx);
                    // A hang guard, far above the fuzzer's 10 s limit (a debug build on a
                    // busy machine is slow; an input that loops is not).
                    assert!(
                        start.elapsed() < Duration::from_secs(60),
                        "{} ran {:?}",
                        file.display(),
                        start.elapsed()
                    );
                    assert!(
                        !matches!(outcome, Outcome::Panicked(_)),
                        "{}: {outcome:?}",
                        file.display()
                    );
                    replayed += 1;
                }
            }
            eprintln!("replayed {replayed} saved fuzz findings");
            std::fs::remove_dir_all(&dir).ok();
        },
    );
}
