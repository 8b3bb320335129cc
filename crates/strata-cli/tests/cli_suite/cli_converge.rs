//! `strata converge` from the command line: its report files and its
//! argument errors (the machinery itself is tested in strata-reports).

const COAT: &str = crate::common::SMOOTH_COAT_OVER_GREY;

/// `strata converge` writes its CSV, markdown and PNG, and rejects bad
/// arguments with a message naming them.
#[test]
fn cli_writes_the_report_files() {
    use std::process::Command;
    let dir = std::env::temp_dir().join(format!("strata-converge-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let mat = dir.join("coat.toml");
    std::fs::write(&mat, COAT).unwrap();
    let out = dir.join("out");
    let bin = env!("CARGO_BIN_EXE_strata");
    let o = Command::new(bin)
        .args(["converge", "--material"])
        .arg(&mat)
        .args([
            "--budget-seconds",
            "0.05",
            "--estimators",
            "scalar,brute:10",
            "--no-cache",
            "--out",
        ])
        .arg(&out)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(
        stdout.contains("scalar") && stdout.contains("brute-10deg"),
        "{stdout}"
    );
    let csv = std::fs::read_to_string(out.join("coat.csv")).unwrap();
    assert!(csv.starts_with("stack,estimator,samples,"));
    assert!(csv.contains("coat,brute-10deg,"));
    assert!(std::fs::read_to_string(out.join("coat-reference.csv"))
        .unwrap()
        .starts_with("kind,"));
    assert!(std::fs::read_to_string(out.join("coat.md"))
        .unwrap()
        .contains("closed form"));
    let png = std::fs::read(out.join("coat.png")).unwrap();
    assert_eq!(&png[..8], b"\x89PNG\r\n\x1a\n");

    let bad = Command::new(bin)
        .args(["converge", "--material"])
        .arg(&mat)
        .args(["--estimators", "scalar,magic", "--no-cache", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("\"magic\""));
    let q = dir.join("q.jsonl");
    std::fs::write(
        &q,
        "{\"wi\":[0,0,1]}\n{\"wi\":[0,0,1],\"wo\":[0,0,\"x\"]}\n",
    )
    .unwrap();
    let bad = Command::new(bin)
        .args(["converge", "--material"])
        .arg(&mat)
        .arg("--queries")
        .arg(&q)
        .args(["--no-cache", "--out"])
        .arg(&out)
        .output()
        .unwrap();
    assert!(!bad.status.success());
    assert!(String::from_utf8_lossy(&bad.stderr).contains("line 2"));
    let _ = std::fs::remove_dir_all(&dir);
}
