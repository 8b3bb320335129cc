//! The command-line tool under abuse: absurd numbers, a stdout that fails or
//! closes, interrupts, unwritable outputs. Every case must end with a message
//! naming the option and value (never a panic or a hang), and leave no
//! temporary file, partial set of outputs or directory it created.

use crate::cli_common;
use cli_common::*;

use std::io::{BufRead, BufReader, Read};
use std::path::Path;
use std::process::{Child, Command, ExitStatus, Output, Stdio};
use std::time::{Duration, Instant};

/// Waits for `child` at most `limit`; a hang is a failure.
fn wait_at_most(child: &mut Child, limit: Duration, what: &str) -> ExitStatus {
    let t = Instant::now();
    loop {
        if let Some(s) = child.try_wait().expect("wait for strata") {
            return s;
        }
        if t.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("strata {what} still running after {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Runs the binary with `args` (no stdin), at most `limit`.
fn run(args: &[&str], limit: Duration) -> Output {
    let mut child = Command::new(EXE)
        .args(args)
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn strata");
    let mut out = child.stdout.take().unwrap();
    let mut err = child.stderr.take().unwrap();
    let o = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = out.read_to_end(&mut v);
        v
    });
    let e = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = err.read_to_end(&mut v);
        v
    });
    let status = wait_at_most(&mut child, limit, &args.join(" "));
    Output {
        status,
        stdout: o.join().unwrap(),
        stderr: e.join().unwrap(),
    }
}

/// Reads `child`'s stderr to its end on a thread while waiting at most
/// `limit` for it: a hang fails the test instead of blocking it.
fn finish(child: &mut Child, limit: Duration, what: &str) -> (ExitStatus, String) {
    let mut err = child.stderr.take().expect("piped stderr");
    let reader = std::thread::spawn(move || {
        let mut v = Vec::new();
        let _ = err.read_to_end(&mut v);
        v
    });
    let status = wait_at_most(child, limit, what);
    (status, text(&reader.join().unwrap()))
}

fn signal(child: &Child, sig: &str) {
    let ok = Command::new("kill")
        .args([sig, &child.id().to_string()])
        .status()
        .expect("run kill");
    assert!(ok.success(), "kill {sig} failed");
}

const SHORT: Duration = Duration::from_secs(60);

#[test]
fn absurd_numbers_are_refused_naming_the_option_and_value() {
    let m = example("coated_copper.toml");
    let bench = |extra: &[&'static str]| -> Vec<&str> {
        let base = [
            "bench",
            "--material",
            &m,
            "--queries",
            "2",
            "--samples",
            "2",
        ];
        [&base[..], extra].concat()
    };
    let cases: Vec<(Vec<&str>, Vec<&str>)> = vec![
        (
            bench(&["--min-seconds", "1e30"]),
            vec!["--min-seconds", "86400"],
        ),
        (bench(&["--min-seconds", "-1"]), vec!["--min-seconds -1"]),
        (bench(&["--min-seconds", "nan"]), vec!["--min-seconds NaN"]),
        (
            vec!["bench", "--queries", "18446744073709551615"],
            vec!["--queries", "18446744073709551615", "1000000"],
        ),
        (
            vec!["bench", "--queries", "100000000000"],
            vec!["--queries", "100000000000"],
        ),
        (
            vec!["bench", "--threads", "100000000000"],
            vec!["--threads", "100000000000", "1024"],
        ),
        (vec!["bench", "--threads", "0"], vec!["--threads", "'0'"]),
        // Walks per query: at most the library's 2^40, refused before any
        // input is read (demo: 2^36, its tables take 16 times as many).
        (
            vec!["eval", "--material", &m, "--samples", "1099511627777"],
            vec!["--samples", "1099511627777", "at most 1099511627776"],
        ),
        (
            vec![
                "albedo",
                "--material",
                &m,
                "--theta",
                "0",
                "--samples",
                "18446744073709551615",
            ],
            vec!["--samples", "18446744073709551615", "at most 1099511627776"],
        ),
        (
            vec!["bench", "--samples", "18446744073709551615"],
            vec!["--samples", "at most 1099511627776"],
        ),
        (
            vec!["demo", "--samples", "68719476737"],
            vec!["--samples", "68719476737", "at most 68719476736"],
        ),
        (
            vec!["eval", "--material", &m, "--threads", "1025"],
            vec!["--threads", "1025", "1024"],
        ),
        (
            vec![
                "albedo",
                "--material",
                &m,
                "--theta",
                "0",
                "--threads",
                "-4",
            ],
            vec!["--threads", "-4"],
        ),
        (
            vec![
                "sample",
                "--material",
                &m,
                "--wi",
                "0,0,1",
                "--count",
                "1",
                "--threads",
                "99999",
            ],
            vec!["--threads", "99999"],
        ),
        (
            vec!["sample", "--material", &m, "--wi", "0,0,1", "--count", "0"],
            vec!["--count", "'0'", "at least 1"],
        ),
        (
            vec!["sample", "--material", &m, "--wi", "0,0,1", "--count", "-1"],
            vec!["--count", "'-1'", "at least 1"],
        ),
        (
            vec!["eval", "--material", &m, "--samples", "-3"],
            vec!["--samples", "'-3'", "at least 1"],
        ),
        (vec!["demo", "--samples", "-3"], vec!["--samples", "'-3'"]),
        (
            vec!["converge", "--material", &m, "--reference-seconds", "-1"],
            vec!["--reference-seconds -1", "> 0"],
        ),
        (
            vec!["converge", "--material", &m, "--reference-seconds", "1e9"],
            vec!["--reference-seconds 1000000000", "86400"],
        ),
        (
            vec!["converge", "--material", &m, "--budget-seconds", "1e30"],
            vec!["--budget-seconds", "86400"],
        ),
        (
            vec!["converge", "--material", &m, "--budget-seconds", "-2"],
            vec!["--budget-seconds -2"],
        ),
    ];
    for (args, needles) in cases {
        let out = run(&args, SHORT);
        assert_fails_with(&out, &needles);
        assert!(out.stdout.is_empty(), "{args:?}: {}", text(&out.stdout));
    }
    // The bounds themselves are accepted.
    let out = run(
        &[
            "sample",
            "--material",
            &m,
            "--wi",
            "0,0,1",
            "--count",
            "2",
            "--threads",
            "1024",
        ],
        SHORT,
    );
    assert!(out.status.success(), "{}", text(&out.stderr));
    assert_eq!(text(&out.stdout).lines().count(), 2);
}

/// `/dev/full` takes nothing: every write fails with "no space left".
#[test]
fn a_failing_stdout_is_an_error_not_a_panic() {
    if !Path::new("/dev/full").exists() {
        return;
    }
    let dir = scratch("dev-full");
    let m = example("coated_copper.toml");
    let runs: Vec<Vec<&str>> = vec![
        vec![
            "bench",
            "--material",
            &m,
            "--queries",
            "2",
            "--samples",
            "4",
            "--min-seconds",
            "0",
        ],
        vec![
            "bench",
            "--json",
            "--material",
            &m,
            "--queries",
            "2",
            "--samples",
            "4",
            "--min-seconds",
            "0",
        ],
        vec![
            "converge",
            "--material",
            &m,
            "--budget-seconds",
            "0.02",
            "--estimators",
            "scalar",
            "--no-cache",
            "--out",
            dir.to_str().unwrap(),
        ],
        vec!["stress", "--quick", "--case", "albedo-1"],
        vec![
            "albedo",
            "--material",
            &m,
            "--theta",
            "10",
            "--samples",
            "100",
        ],
    ];
    for args in runs {
        let full = std::fs::OpenOptions::new()
            .write(true)
            .open("/dev/full")
            .unwrap();
        let mut child = Command::new(EXE)
            .args(&args)
            .stdout(full)
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        let (status, err) = finish(&mut child, SHORT, &args.join(" "));
        assert_eq!(status.code(), Some(1), "{args:?}: {err}");
        assert!(err.contains("cannot write to stdout"), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
    }
    // converge failed: it wrote none of its outputs.
    assert_eq!(names(&dir), Vec::<String>::new());
}

/// A reader that closes the pipe early (`strata ... | head`) ends the
/// printing quietly; the files are still written.
#[test]
fn a_closed_pipe_ends_quietly() {
    let dir = scratch("closed-pipe");
    let m = example("coated_copper.toml");
    let runs: Vec<Vec<&str>> = vec![
        vec![
            "bench",
            "--material",
            &m,
            "--queries",
            "2",
            "--samples",
            "4",
            "--min-seconds",
            "0.3",
        ],
        vec![
            "converge",
            "--material",
            &m,
            "--budget-seconds",
            "0.02",
            "--estimators",
            "scalar",
            "--no-cache",
            "--out",
            dir.to_str().unwrap(),
        ],
        vec!["stress", "--quick", "--case", "albedo-1"],
    ];
    for args in runs {
        let mut child = Command::new(EXE)
            .args(&args)
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        drop(child.stdout.take()); // the reader is gone before anything is printed
        let (status, err) = finish(&mut child, SHORT, &args.join(" "));
        assert!(status.success(), "{args:?}: {status}: {err}");
        for noise in ["panicked", "cannot write to stdout", "Broken pipe"] {
            assert!(!err.contains(noise), "{args:?}: {err}");
        }
    }
    assert_eq!(
        names(&dir),
        [
            "coated_copper-reference.csv",
            "coated_copper.csv",
            "coated_copper.md",
            "coated_copper.png"
        ]
    );
}

#[test]
fn an_interrupted_demo_removes_the_directory_it_created() {
    let dir = scratch("interrupt-demo");
    let out = dir.join("new").join("figures");
    let mut child = Command::new(EXE)
        .args([
            "demo",
            "--samples",
            "100000",
            "--out",
            out.to_str().unwrap(),
        ])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // The directory is made (and probed) before the work starts.
    let t = Instant::now();
    while !out.is_dir() {
        assert!(t.elapsed() < SHORT, "demo never created {}", out.display());
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    signal(&child, "-INT");
    let (status, err) = finish(&mut child, SHORT, "demo");
    assert_eq!(status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    assert_eq!(names(&dir), Vec::<String>::new(), "left behind");
}

/// `converge --suite docs` keeps the finished stacks' outputs in temporary
/// files until the last stack is done: SIGTERM in between removes them, and
/// the output directory it created.
#[test]
fn an_interrupted_converge_leaves_no_temporary_or_partial_output() {
    let dir = scratch("interrupt-converge");
    let out = dir.join("results");
    let mut child = Command::new(EXE)
        .args([
            "converge",
            "--suite",
            "docs",
            "--budget-seconds",
            "0.05",
            "--no-cache",
        ])
        .args(["--reference-seconds", "600", "--out", out.to_str().unwrap()])
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    // stderr line by line on a thread, so that a silent hang fails the test.
    let err = BufReader::new(child.stderr.take().unwrap());
    let (tx, lines) = std::sync::mpsc::channel::<String>();
    let reader = std::thread::spawn(move || {
        for line in err.lines().map_while(Result::ok) {
            let _ = tx.send(line);
        }
    });
    let mut log = String::new();
    // The first stack (closed-form reference) is quick; wait for the second.
    loop {
        let line = match lines.recv_timeout(SHORT) {
            Ok(line) => line,
            Err(e) => {
                let _ = child.kill();
                panic!("no line from converge ({e:?}): {log}");
            }
        };
        log.push_str(&line);
        log.push('\n');
        if line.starts_with("coated-conductor:") {
            break;
        }
    }
    let staged = names(&out);
    assert!(
        staged.iter().any(|n| n.starts_with(".clear-coat.csv.tmp")),
        "the first stack's outputs are staged: {staged:?}"
    );
    assert!(
        !staged.iter().any(|n| n == "clear-coat.csv"),
        "no output is in place before the last stack: {staged:?}"
    );
    signal(&child, "-TERM");
    let status = wait_at_most(&mut child, SHORT, "converge");
    reader.join().unwrap();
    let rest: String = lines.try_iter().map(|l| l + "\n").collect();
    assert_eq!(status.code(), Some(130), "{log}{rest}");
    assert!(rest.contains("interrupted"), "{rest}");
    assert_eq!(names(&dir), Vec::<String>::new(), "left behind");
}

#[test]
fn converge_checks_its_outputs_before_the_work() {
    let dir = scratch("converge-out");
    let m = example("coated_copper.toml");
    let base = [
        "converge",
        "--material",
        &m,
        "--budget-seconds",
        "0.05",
        "--estimators",
        "scalar",
        "--no-cache",
        "--out",
    ];
    // A directory in place of the plot: refused at once, nothing written.
    let out = dir.join("a");
    std::fs::create_dir_all(out.join("coated_copper.png")).unwrap();
    let o = run(&[&base[..], &[out.to_str().unwrap()]].concat(), SHORT);
    assert_fails_with(&o, &["--out", "coated_copper.png", "directory"]);
    // It failed before the work: no stack's summary was printed.
    assert!(
        o.stdout.is_empty(),
        "it failed after the work: {}",
        text(&o.stdout)
    );
    assert_eq!(names(&out), ["coated_copper.png"]);
    assert!(out.join("coated_copper.png").is_dir());
    // A file in place of the output directory, or of one of its parents.
    let file = dir.join("file");
    std::fs::write(&file, "x").unwrap();
    for target in [file.clone(), file.join("sub")] {
        let o = run(&[&base[..], &[target.to_str().unwrap()]].concat(), SHORT);
        assert_fails_with(&o, &["--out", "file", "cannot create"]);
        assert!(o.stdout.is_empty(), "{}", text(&o.stdout));
    }
    // A file in place of the cache directory.
    let o = run(
        &[
            "converge",
            "--material",
            &m,
            "--budget-seconds",
            "0.05",
            "--estimators",
            "scalar",
            "--cache",
            file.to_str().unwrap(),
            "--out",
            dir.join("b").to_str().unwrap(),
        ],
        SHORT,
    );
    assert_fails_with(&o, &["--cache", "file"]);
    assert_eq!(
        names(&dir),
        ["a", "file"],
        "no output directory left behind"
    );
    assert_eq!(std::fs::read(&file).unwrap(), b"x");
    // demo likewise: a file as --out fails before the work.
    let o = run(
        &["demo", "--samples", "4", "--out", file.to_str().unwrap()],
        SHORT,
    );
    assert_fails_with(&o, &["--out", "file", "not a directory"]);
    assert!(o.stdout.is_empty(), "{}", text(&o.stdout));
}

#[test]
fn converge_refuses_queries_from_below_an_opaque_stack() {
    let dir = scratch("converge-below");
    let m = example("coated_copper.toml");
    let out = dir.join("out");
    for (q, why) in [
        (r#"{"wi":[0,0,-1],"wo":[0,0,1]}"#, "light from below"),
        (
            r#"{"wi":[0,0,1],"wo":[0.3,0,-1]}"#,
            "wo is on the other side",
        ),
        (r#"{"wi":[0.2,0,-1]}"#, "light from below"),
        (r#"{"wi":[1,0,1e-20]}"#, "within cos 1e-18 of the horizon"),
    ] {
        let file = dir.join("q.jsonl");
        std::fs::write(&file, format!("# a comment\n{{\"wi\":[0,0,1]}}\n{q}\n")).unwrap();
        let o = run(
            &[
                "converge",
                "--material",
                &m,
                "--queries",
                file.to_str().unwrap(),
                "--budget-seconds",
                "0.05",
                "--no-cache",
                "--out",
                out.to_str().unwrap(),
            ],
            SHORT,
        );
        // The line is quoted as given, not normalized.
        let needle = format!("line 3 ({q})");
        assert_fails_with(&o, &["--queries", "q.jsonl", &needle, "coated_copper", why]);
        assert!(!out.exists(), "nothing written for {q}");
    }
    // A two-sided opaque stack mirrors light from below: a fine query (the
    // engines answer it), and so is a view on the same side as the light.
    let two_sided = dir.join("two_sided.toml");
    std::fs::write(
        &two_sided,
        format!("two_sided = true\n{}", std::fs::read_to_string(&m).unwrap()),
    )
    .unwrap();
    let file = dir.join("q.jsonl");
    std::fs::write(
        &file,
        "{\"wi\":[0.3,0,-0.9],\"wo\":[-0.2,0,-0.9]}\n{\"wi\":[0.1,0,-1]}\n",
    )
    .unwrap();
    let o = run(
        &[
            "converge",
            "--material",
            two_sided.to_str().unwrap(),
            "--queries",
            file.to_str().unwrap(),
            "--budget-seconds",
            "0.05",
            "--estimators",
            "scalar",
            "--no-cache",
            "--reference-seconds",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        SHORT,
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    assert!(
        names(&out).contains(&"two_sided.csv".to_string()),
        "{:?}",
        names(&out)
    );
    let _ = std::fs::remove_dir_all(&out);
    // Viewed from the other side of the light, even two-sided, it is not.
    std::fs::write(&file, "{\"wi\":[0.3,0,-0.9],\"wo\":[-0.2,0,0.9]}\n").unwrap();
    let o = run(
        &[
            "converge",
            "--material",
            two_sided.to_str().unwrap(),
            "--queries",
            file.to_str().unwrap(),
            "--no-cache",
            "--out",
            out.to_str().unwrap(),
        ],
        SHORT,
    );
    assert_fails_with(&o, &["line 1", "wo is on the other side"]);
    // From below a transmissive stack is a fine query.
    let file = dir.join("q.jsonl");
    std::fs::write(
        &file,
        "{\"wi\":[0,0,-1],\"wo\":[0,0.3,1]}\n{\"wi\":[0.1,0,-1]}\n",
    )
    .unwrap();
    let o = run(
        &[
            "converge",
            "--material",
            &example("scattering_slab.toml"),
            "--queries",
            file.to_str().unwrap(),
            "--budget-seconds",
            "0.05",
            "--estimators",
            "scalar",
            "--no-cache",
            "--reference-seconds",
            "2",
            "--out",
            out.to_str().unwrap(),
        ],
        SHORT,
    );
    assert!(o.status.success(), "{}", text(&o.stderr));
    let written = names(&out);
    assert_eq!(written.len(), 4, "{written:?}");
    for n in written {
        let t = std::fs::read(out.join(&n)).unwrap();
        if n.ends_with(".csv") || n.ends_with(".md") {
            let t = text(&t).to_lowercase();
            assert!(!t.contains("inf") && !t.contains("nan"), "{n}: {t}");
        }
    }
}
