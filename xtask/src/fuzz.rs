//! `cargo xtask fuzz`: a mutation fuzzer on the stable toolchain over the project's own
//! seed files (exported built-in glTF/GLB, EXR of every compression, PNG, camera lists).
//!
//! The parent process runs one **worker** per target (`xtask fuzz-worker`, a hidden
//! command) under an address-space limit (`ulimit -v`). The worker mutates seeds (byte
//! flips, interesting integers, insertions and deletions, truncation, splicing two inputs,
//! and for JSON targets edits of the parsed value: numbers set to extremes, keys removed,
//! strings replaced by hostile URIs, array elements duplicated) and runs each input under
//! `catch_unwind`. Before each input it writes the input to `DIR/<target>/current`; every
//! second it reports how many inputs it ran. The parent kills a worker that stays silent
//! past the time limit (a hang), and restarts one that dies (an abort, or an allocation past
//! the cap). Every failing input (panic, abort, out of memory, hang) is saved under
//! `tests/fuzz-regressions/<target>/`, which an ordinary test replays.

use std::io::{BufRead, BufReader, Write};
use std::path::{Path, PathBuf};
use std::process::Stdio;
use std::sync::mpsc;
use std::time::{Duration, Instant};

use golden_tests::fuzz::{self, Context, Outcome, Target};
use scene_core::sampling::Rng;
use serde_json::Value;

/// Address space of a worker: the fuzz budget (256 MiB an image, 512 MiB a scene) with
/// room for the binary, thread stacks and allocator arenas.
const WORKER_ADDRESS_SPACE: u64 = 3 << 30;

/// An input that runs longer than this is a hang.
const INPUT_TIME_LIMIT: Duration = Duration::from_secs(10);

/// A worker that is not ready to fuzz after this long is a hang.
const SETUP_TIME_LIMIT: Duration = Duration::from_secs(120);

/// Options of `cargo xtask fuzz`.
pub struct Options {
    /// Targets to run (all when empty).
    pub targets: Vec<String>,
    /// Seconds per target.
    pub seconds: u64,
    /// Seed of the mutations.
    pub seed: u64,
    /// Working directory (current inputs, scratch files).
    pub dir: PathBuf,
    /// Targets run at once.
    pub jobs: usize,
}

/// What one target's run found.
#[derive(Default, Debug)]
struct Summary {
    inputs: u64,
    refused: u64,
    panics: u64,
    aborts: u64,
    hangs: u64,
    peak_kib: u64,
    restarts: u64,
}

/// Every fuzz target: the loaders' and the scenes' (`golden_tests::fuzz`), and `cli`, the
/// command lines of this binary ([`crate::fuzz_command_line`]: parsed and every number
/// checked against its range, nothing run).
pub fn targets() -> Vec<Target> {
    let mut all = fuzz::targets();
    all.push(Target {
        name: "cli",
        ext: "json",
        json: true,
        seeds: cli_seeds,
        run: |bytes, _| crate::fuzz_command_line(bytes),
    });
    all.push(Target {
        name: "commands",
        ext: "json",
        json: true,
        seeds: command_seeds,
        run: |bytes, ctx| crate::fuzz_run_command(bytes, &ctx.scratch),
    });
    all
}

/// Command lines the `commands` target runs ([`crate::fuzz_run_command`]): each command at
/// a tiny size, with far lights, degenerate skies and the options of the last round.
fn command_seeds() -> Vec<Vec<u8>> {
    [
        r#"["reference", "--scene", "cornell", "--width", "8", "--height", "6", "--spp", "2", "--bounces", "inf"]"#,
        r#"["reference", "--scene", "cornell-point", "--width", "8", "--height", "6", "--spp", "1", "--point", "1e38,1e38,1e38=1"]"#,
        r#"["relight", "--scene", "cornell", "--elements", "64", "--width", "8", "--height", "6", "--light", "emissive:3=1,0.5,0.2"]"#,
        r#"["relight", "--scene", "corridor", "--elements", "128", "--width", "8", "--height", "6", "--solver", "hierarchical", "--point", "1e38,0,0=1"]"#,
        r#"["relight", "--scene", "primitives", "--elements", "64", "--width", "8", "--height", "6", "--sky", "1,1,1", "--sky-directions", "2"]"#,
        r#"["ibrr", "--scene", "cornell", "--ldc", "16", "--irpls", "8", "--width", "8", "--height", "6", "--f16"]"#,
        r#"["ibrr", "--scene", "cornell-point", "--ldc", "16", "--irpls", "8", "--width", "8", "--height", "6", "--point", "1e38,1e38,1e38=1"]"#,
        r#"["ibrr", "--scene", "primitives", "--ldc", "16", "--irpls", "4", "--width", "8", "--height", "6", "--sun", "0,-1,0=1e11", "--f16"]"#,
        r#"["export-gltf", "--scene", "cornell", "--out", "x.glb"]"#,
        r#"["export-gltf", "--scene", "primitives", "--out", "x.gltf", "--sky", "0.5"]"#,
    ]
    .map(|s| s.as_bytes().to_vec())
    .to_vec()
}

/// Command lines of every command with its numbers, as JSON arrays of arguments.
fn cli_seeds() -> Vec<Vec<u8>> {
    [
        r#"["reference", "--width", "256", "--height", "256", "--spp", "64", "--exposure", "0", "--bounces", "1"]"#,
        r#"["reference", "--width", "4294967295", "--spp", "0", "--exposure", "NaN", "--bounces", "inf"]"#,
        r#"["relight", "--elements", "4096", "--subpixels", "8", "--emitter-rays", "4", "--hemicube-resolution", "128", "--max-unshot", "0.001", "--split-depth", "6", "--width", "64", "--height", "48", "--light", "point:0=1,1,1"]"#,
        r#"["relight", "--subpixels", "4000000000", "--emitter-rays", "4294967295", "--max-unshot=-1e308"]"#,
        r#"["ibrr", "--ldc", "256", "--irpls", "184", "--clamp", "0", "--exposure", "1", "--seed", "3"]"#,
        r#"["experiment", "--views", "2", "--spp", "512", "--size", "256x192", "--repeats", "3", "--sequence-frames", "8", "--sequence-spp", "64", "--bounces", "1,inf", "--techniques", "dl,isr-24,relight-256,ibrr-128-64"]"#,
        r#"["experiment", "--views", "18446744073709551615", "--size", "99999x0", "--techniques", "isr-0,relight-99999999999"]"#,
        r#"["sweep-isr", "--size", "64x48", "--spp", "16"]"#,
        r#"["bench", "reference", "--threads", "2", "--repeats", "5"]"#,
        r#"["fuzz", "--seconds", "60", "--jobs", "2", "--seed", "1"]"#,
        r#"["experiment", "--preset", "full", "--shard", "2/4", "--still-repeats", "3", "--write-docs", "out/r.md"]"#,
        r#"["experiment", "--shard", "0/0", "--preset", "huge", "--still-repeats", "4294967295"]"#,
        r#"["experiment", "merge", "out/a", "out/b", "--out", "out/m"]"#,
    ]
    .map(|s| s.as_bytes().to_vec())
    .to_vec()
}

/// `cargo xtask fuzz`.
pub fn run(opts: &Options) -> Result<(), String> {
    // The numbers were checked by `Command::check_numbers`.
    let all = targets();
    let names: Vec<&str> = if opts.targets.is_empty() {
        all.iter().map(|t| t.name).collect()
    } else {
        for t in &opts.targets {
            if !all.iter().any(|a| a.name == t) {
                let known: Vec<&str> = all.iter().map(|a| a.name).collect();
                return Err(format!(
                    "unknown fuzz target '{t}' (known: {})",
                    known.join(", ")
                ));
            }
        }
        opts.targets.iter().map(String::as_str).collect()
    };
    println!(
        "fuzzing {} for {} s each, {} at a time, seed {}, worker address space {} MiB, input \
         time limit {} s",
        names.join(", "),
        opts.seconds,
        opts.jobs.max(1),
        opts.seed,
        WORKER_ADDRESS_SPACE >> 20,
        INPUT_TIME_LIMIT.as_secs()
    );
    let mut results: Vec<(String, Summary)> = Vec::new();
    for chunk in names.chunks(opts.jobs.max(1)) {
        let handles: Vec<_> = chunk
            .iter()
            .map(|name| {
                let name = name.to_string();
                let dir = opts.dir.join(&name);
                let (seconds, seed) = (opts.seconds, opts.seed);
                std::thread::spawn(move || {
                    let s = supervise(&name, &dir, seconds, seed);
                    (name, s)
                })
            })
            .collect();
        // Join every supervisor of the chunk before reporting a failure of one.
        let joined: Vec<_> = handles.into_iter().map(|h| h.join()).collect();
        for j in joined {
            let (name, s) = j.map_err(|_| "a supervisor thread panicked")?;
            let s = s?;
            println!("[{name}] finished: {s:?}");
            results.push((name, s));
        }
    }
    println!(
        "\n| target | inputs | refused | panics | aborts/OOM | hangs | worker restarts | peak RSS |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let mut findings = 0;
    for (name, s) in &results {
        println!(
            "| {name} | {} | {} | {} | {} | {} | {} | {} MiB |",
            s.inputs,
            s.refused,
            s.panics,
            s.aborts,
            s.hangs,
            s.restarts,
            s.peak_kib / 1024
        );
        findings += s.panics + s.aborts + s.hangs;
    }
    if findings > 0 {
        Err(format!(
            "{findings} failing input(s) saved under {}",
            fuzz::regressions_root().display()
        ))
    } else {
        Ok(())
    }
}

/// Runs workers for `name` until `seconds` have passed, restarting them after a crash or a
/// hang, and saving the input that caused it.
fn supervise(name: &str, dir: &Path, seconds: u64, seed: u64) -> Result<Summary, String> {
    std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    let exe = std::env::current_exe().map_err(|e| e.to_string())?;
    let deadline = Instant::now() + Duration::from_secs(seconds);
    let mut summary = Summary::default();
    let mut round = 0u64;
    while Instant::now() < deadline {
        let left = deadline
            .saturating_duration_since(Instant::now())
            .as_secs()
            .max(1);
        // A worker that dies before its first input must not be blamed on an old one.
        let _ = std::fs::remove_file(dir.join("current"));
        let mut child = golden_tests::child::capped_command(&exe, WORKER_ADDRESS_SPACE)
            .args(["fuzz-worker", "--target", name, "--seconds"])
            .arg(left.to_string())
            .arg("--seed")
            .arg(scene_core::sampling::hash_seed(seed, round, 0).to_string())
            .arg("--dir")
            .arg(dir)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .map_err(|e| format!("spawn the fuzz worker: {e}"))?;
        let stdout = child.stdout.take().ok_or("worker stdout")?;
        let (tx, rx) = mpsc::channel::<String>();
        std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines().map_while(Result::ok) {
                if tx.send(line).is_err() {
                    break;
                }
            }
        });
        let mut done = false;
        let mut hung = false;
        let mut ready = false;
        let mut fatal = None;
        let mut last_inputs = 0;
        loop {
            // Setting up (seeds, scratch files) gets longer than one input.
            let wait = if ready {
                INPUT_TIME_LIMIT
            } else {
                SETUP_TIME_LIMIT
            };
            match rx.recv_timeout(wait) {
                Ok(line) => {
                    let mut parts = line.split_whitespace();
                    match parts.next() {
                        Some("ready") => ready = true,
                        Some("progress") => last_inputs = parse_next(&mut parts),
                        Some("panic") => {
                            summary.panics += 1;
                            println!("[{name}] panic: {}", line.trim_start_matches("panic "));
                        }
                        Some("done") => {
                            last_inputs = parse_next(&mut parts);
                            summary.refused += parse_next(&mut parts);
                            summary.peak_kib = summary.peak_kib.max(parse_next(&mut parts));
                            done = true;
                            break;
                        }
                        Some("fatal") => {
                            fatal = Some(line.trim_start_matches("fatal ").to_string());
                            break;
                        }
                        _ => {}
                    }
                }
                Err(mpsc::RecvTimeoutError::Timeout) => {
                    let _ = child.kill();
                    hung = true;
                    summary.hangs += 1;
                    let saved = save_current(name, dir, "hang")?;
                    println!("[{name}] hang: no word from the worker for {wait:?}: {saved}");
                    break;
                }
                Err(mpsc::RecvTimeoutError::Disconnected) => break,
            }
        }
        let status = child.wait().map_err(|e| e.to_string())?;
        summary.inputs += last_inputs;
        if let Some(message) = fatal {
            return Err(format!("[{name}] the fuzz worker failed: {message}"));
        }
        if done {
            break;
        }
        if !hung {
            // Died without reporting: an abort, or an allocation over the cap.
            summary.aborts += 1;
            let saved = save_current(name, dir, "abort")?;
            println!("[{name}] worker died ({status}): {saved}");
        }
        summary.restarts += 1;
        round += 1;
    }
    Ok(summary)
}

fn parse_next<'a>(parts: &mut impl Iterator<Item = &'a str>) -> u64 {
    parts.next().and_then(|s| s.parse().ok()).unwrap_or(0)
}

/// Copies the worker's current input into the regression folder (there is none when the
/// worker died while setting up).
fn save_current(name: &str, dir: &Path, why: &str) -> Result<String, String> {
    match std::fs::read(dir.join("current")) {
        Ok(bytes) => save_finding(name, &bytes, why),
        Err(_) => Ok("no input yet (the worker was setting up)".into()),
    }
}

fn save_finding(name: &str, bytes: &[u8], why: &str) -> Result<String, String> {
    let targets = targets();
    let ext = targets
        .iter()
        .find(|t| t.name == name)
        .map_or("bin", |t| t.ext);
    let folder = fuzz::regressions_root().join(name);
    std::fs::create_dir_all(&folder).map_err(|e| e.to_string())?;
    let path = folder.join(format!("{why}-{}.{ext}", fuzz::content_name(bytes)));
    std::fs::write(&path, bytes).map_err(|e| e.to_string())?;
    Ok(path.display().to_string())
}

/// `xtask fuzz-worker`: mutates and runs inputs of one target until `seconds` pass. A
/// failure of the harness itself (not of an input) is reported as a `fatal` line.
pub fn worker(name: &str, seconds: u64, seed: u64, dir: &Path) -> Result<(), String> {
    let result = fuzz_loop(name, seconds, seed, dir);
    if let Err(e) = &result {
        println!("fatal {}", e.replace('\n', " "));
    }
    result
}

fn fuzz_loop(name: &str, seconds: u64, seed: u64, dir: &Path) -> Result<(), String> {
    // Panics are caught and reported; the default hook's message would only be noise.
    std::panic::set_hook(Box::new(|_| {}));
    let targets = targets();
    let target = targets
        .iter()
        .find(|t| t.name == name)
        .ok_or_else(|| format!("unknown target {name}"))?;
    let ctx = Context::new(fuzz::fuzz_budget(), &dir.join("scratch"));
    let mut corpus = (target.seeds)();
    for p in fuzz::regressions(target) {
        if let Ok(b) = std::fs::read(&p) {
            corpus.push(b);
        }
    }
    let mut rng = Rng::new(seed, 0x6675_7a7a);
    let current = dir.join("current");
    let deadline = Instant::now() + Duration::from_secs(seconds);
    let mut last_report = Instant::now();
    let (mut inputs, mut refused) = (0u64, 0u64);
    let stdout = std::io::stdout();
    let _ = writeln!(stdout.lock(), "ready");
    while Instant::now() < deadline {
        let input = mutate(target, &corpus, &mut rng);
        std::fs::write(&current, &input).map_err(|e| e.to_string())?;
        match fuzz::run(target, &input, &ctx) {
            Outcome::Ok => {
                // Inputs that still load are good material for more mutations.
                if corpus.len() < 256 && rng.below(8) == 0 {
                    corpus.push(input);
                }
            }
            Outcome::Refused(_) => refused += 1,
            Outcome::Panicked(msg) => {
                let saved = save_finding(name, &input, "panic")?;
                let msg = msg.replace('\n', " ");
                let _ = writeln!(stdout.lock(), "panic {saved} {msg}");
            }
        }
        inputs += 1;
        if last_report.elapsed() >= Duration::from_secs(1) {
            let _ = writeln!(stdout.lock(), "progress {inputs}");
            last_report = Instant::now();
        }
    }
    let _ = writeln!(
        stdout.lock(),
        "done {inputs} {refused} {}",
        crate::peak_rss_kib()
    );
    Ok(())
}

/// One new input: a corpus entry under one to four stacked mutations.
fn mutate(target: &Target, corpus: &[Vec<u8>], rng: &mut Rng) -> Vec<u8> {
    let pick = |rng: &mut Rng| corpus[rng.below(corpus.len() as u32) as usize].clone();
    let mut data = pick(rng);
    if target.json
        && rng.below(2) == 0
        && let Ok(mut v) = serde_json::from_slice::<Value>(&data)
    {
        for _ in 0..1 + rng.below(3) {
            mutate_json(&mut v, rng);
        }
        if let Ok(bytes) = serde_json::to_vec(&v) {
            return bytes;
        }
    }
    for _ in 0..1 + rng.below(4) {
        mutate_bytes(&mut data, &pick(rng), rng);
    }
    data
}

const INTERESTING: [u64; 12] = [
    0,
    1,
    0x7f,
    0xff,
    0x7fff,
    0xffff,
    0x7fff_ffff,
    0xffff_ffff,
    0x8000_0000,
    0x0001_0000,
    0x4000_0000,
    0x7fff_ffff_ffff_ffff,
];

fn mutate_bytes(data: &mut Vec<u8>, other: &[u8], rng: &mut Rng) {
    if data.is_empty() {
        data.push(rng.next_u32() as u8);
        return;
    }
    let at = rng.below(data.len() as u32) as usize;
    match rng.below(8) {
        // Flip one bit.
        0 => data[at] ^= 1 << rng.below(8),
        // A random byte.
        1 => data[at] = rng.next_u32() as u8,
        // An interesting integer, 1, 2, 4 or 8 bytes, little-endian.
        2 => {
            let v = INTERESTING[rng.below(INTERESTING.len() as u32) as usize];
            let width = 1usize << rng.below(4);
            let v = if rng.below(2) == 0 {
                v
            } else {
                v.wrapping_neg()
            };
            for (i, b) in v.to_le_bytes().iter().take(width).enumerate() {
                if let Some(slot) = data.get_mut(at + i) {
                    *slot = *b;
                }
            }
        }
        // Truncate.
        3 => data.truncate(at),
        // Delete a run.
        4 => {
            let end = (at + 1 + rng.below(64) as usize).min(data.len());
            data.drain(at..end);
        }
        // Duplicate a run.
        5 => {
            let end = (at + 1 + rng.below(64) as usize).min(data.len());
            let run: Vec<u8> = data[at..end].to_vec();
            let to = rng.below(data.len() as u32 + 1) as usize;
            data.splice(to..to, run);
        }
        // Splice: our head, another input's tail.
        6 if !other.is_empty() => {
            let from = rng.below(other.len() as u32) as usize;
            data.truncate(at);
            data.extend_from_slice(&other[from..]);
        }
        // Overwrite a run with another input's bytes at the same offset.
        _ => {
            let len = (1 + rng.below(32) as usize).min(data.len() - at);
            for i in 0..len {
                if let Some(&b) = other.get(at + i) {
                    data[at + i] = b;
                }
            }
        }
    }
}

const HOSTILE_STRINGS: [&str; 12] = [
    "",
    "file:///etc/passwd",
    "file:///dev/zero",
    "/dev/zero",
    "/etc/hostname",
    "../outside.bin",
    "buf.bin",
    "sub/../../outside.bin",
    "%FF%FE.bin",
    "http://example.invalid/x.bin",
    "data:application/octet-stream;base64,AAAA",
    "data:image/png;base64,iVBORw0KGgo=",
];

const HOSTILE_NUMBERS: [f64; 14] = [
    0.0,
    -1.0,
    1.0,
    1e39,
    -1e39,
    1e-45,
    1e308,
    4294967295.0,
    4294967296.0,
    2147483648.0,
    67108864.0,
    9007199254740993.0,
    3.0,
    65536.0,
];

/// Edits one node of a parsed JSON document, chosen uniformly among all nodes.
fn mutate_json(v: &mut Value, rng: &mut Rng) {
    let n = count_nodes(v);
    let target = rng.below(n.min(u32::MAX as usize) as u32) as usize;
    let mut seen = 0;
    edit_nth(v, target, &mut seen, rng);
}

fn count_nodes(v: &Value) -> usize {
    1 + match v {
        Value::Array(a) => a.iter().map(count_nodes).sum(),
        Value::Object(o) => o.values().map(count_nodes).sum(),
        _ => 0,
    }
}

fn edit_nth(v: &mut Value, target: usize, seen: &mut usize, rng: &mut Rng) -> bool {
    if *seen == target {
        edit_node(v, rng);
        return true;
    }
    *seen += 1;
    match v {
        Value::Array(a) => a.iter_mut().any(|c| edit_nth(c, target, seen, rng)),
        Value::Object(o) => o.values_mut().any(|c| edit_nth(c, target, seen, rng)),
        _ => false,
    }
}

fn edit_node(v: &mut Value, rng: &mut Rng) {
    let number = |rng: &mut Rng| {
        let x = HOSTILE_NUMBERS[rng.below(HOSTILE_NUMBERS.len() as u32) as usize];
        serde_json::Number::from_f64(x).map_or(Value::Null, |n| {
            if x.fract() == 0.0 && x.abs() < 1e19 && rng.below(2) == 0 {
                Value::from(x as i64)
            } else {
                Value::Number(n)
            }
        })
    };
    match v {
        Value::Number(_) => *v = number(rng),
        Value::String(_) => {
            *v = Value::from(HOSTILE_STRINGS[rng.below(HOSTILE_STRINGS.len() as u32) as usize])
        }
        Value::Array(a) if !a.is_empty() => {
            let i = rng.below(a.len() as u32) as usize;
            match rng.below(3) {
                0 => {
                    let c = a[i].clone();
                    a.push(c);
                }
                1 => {
                    a.remove(i);
                }
                _ => a.truncate(i),
            }
        }
        Value::Object(o) if !o.is_empty() => {
            let keys: Vec<String> = o.keys().cloned().collect();
            let k = &keys[rng.below(keys.len() as u32) as usize];
            match rng.below(3) {
                0 => {
                    o.remove(k);
                }
                1 => {
                    o.insert(k.clone(), number(rng));
                }
                _ => {
                    o.insert(k.clone(), Value::Array(vec![]));
                }
            }
        }
        _ => *v = number(rng),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The `cli` target's seeds and saved findings (`tests/fuzz-regressions/cli/`) parse
    /// and check without a panic; the good seeds are accepted and the hostile ones refused
    /// naming the argument.
    #[test]
    fn command_lines_are_checked_without_a_panic() {
        let all = targets();
        let cli = all.iter().find(|t| t.name == "cli").unwrap();
        let dir = std::env::temp_dir().join(format!("xtask-cli-fuzz-{}", std::process::id()));
        let ctx = Context::new(fuzz::fuzz_budget(), &dir);
        let mut inputs = (cli.seeds)();
        for p in fuzz::regressions(cli) {
            inputs.push(std::fs::read(p).unwrap());
        }
        let mut outcomes = Vec::new();
        for input in &inputs {
            let o = fuzz::run(cli, input, &ctx);
            assert!(
                !matches!(o, Outcome::Panicked(_)),
                "{}: {o:?}",
                String::from_utf8_lossy(input)
            );
            outcomes.push(o);
        }
        std::fs::remove_dir_all(&dir).ok();
        assert_eq!(outcomes[0], Outcome::Ok);
        assert!(
            matches!(&outcomes[1], Outcome::Refused(e) if e.contains("--width")),
            "{:?}",
            outcomes[1]
        );
        assert!(
            matches!(&outcomes[3], Outcome::Refused(e) if e.contains("--max-unshot = -1e308")),
            "{:?}",
            outcomes[3]
        );
        assert!(matches!(&outcomes[6], Outcome::Refused(_)));
        assert!(
            matches!(&outcomes[11], Outcome::Refused(e) if e.contains("unknown preset")),
            "{:?}",
            outcomes[11]
        );
        for i in [2, 4, 5, 7, 8, 9, 10, 12] {
            assert_eq!(outcomes[i], Outcome::Ok, "seed {i}");
        }
    }

    /// The `commands` target's seeds run their commands to completion (far lights, f16
    /// layers, skies of two directions, every command it runs), each writing finite images,
    /// and an ask beyond its tiny sizes is refused naming it.
    #[test]
    fn the_commands_target_runs_its_seeds_and_refuses_large_asks() {
        let all = targets();
        let commands = all.iter().find(|t| t.name == "commands").unwrap();
        let dir = std::env::temp_dir().join(format!("xtask-commands-fuzz-{}", std::process::id()));
        let ctx = Context::new(fuzz::fuzz_budget(), &dir);
        for input in (commands.seeds)() {
            let o = fuzz::run(commands, &input, &ctx);
            assert_eq!(o, Outcome::Ok, "{}", String::from_utf8_lossy(&input));
        }
        let large = br#"["reference", "--scene", "cornell", "--width", "64", "--height", "48", "--spp", "1"]"#;
        let o = fuzz::run(commands, large, &ctx);
        assert!(
            matches!(&o, Outcome::Refused(e) if e.contains("pixels 3072")),
            "{o:?}"
        );
        let file =
            br#"["relight", "--scene", "/etc/passwd.gltf", "--width", "8", "--height", "6"]"#;
        let o = fuzz::run(commands, file, &ctx);
        assert!(
            matches!(&o, Outcome::Refused(e) if e.contains("built-in")),
            "{o:?}"
        );
        std::fs::remove_dir_all(&dir).ok();
    }
}
