//! `strata eval`'s input as a program drives it: answers as the lines
//! arrive, and input errors that name where they are (a JSON material's
//! field, a table written as an array, a set path given twice).

use crate::cli_common;
use cli_common::*;
use std::io::{BufRead, BufReader, Write};
use std::process::{Command, Stdio};
use std::sync::mpsc;
use std::time::Duration;

/// `strata eval` answers a line written to a pipe before the next one is
/// written, with the answers it gives the same lines read from a file (it
/// once waited for 1024 lines or the end of its input, so a program that
/// wrote one query and waited for its answer waited for ever).
#[test]
fn eval_answers_each_line_as_it_arrives() {
    let dir = scratch("input-stream");
    let queries = [
        r#"{"wi":[0.3,0.1,0.9],"wo":[-0.2,0.4,0.8]}"#,
        r#"{"wi":[0,0,1],"wo":[0.5,0,0.8],"set":{"layers[0].interface.roughness":0.3}}"#,
        r#"{"wi":[0.7,0,0.5],"wo":[0,0.6,0.7]}"#,
    ];
    let file = dir.join("queries.jsonl");
    std::fs::write(&file, queries.join("\n") + "\n").expect("write queries");
    for material in ["clear_coat_lambertian.toml", "coated_copper.toml"] {
        let m = example(material);
        let args = ["eval", "--material", &m, "--samples", "64"];
        // From a file: the reference answers.
        let batch = Command::new(EXE)
            .args(args)
            .stdin(std::fs::File::open(&file).expect("open queries"))
            .output()
            .expect("run strata");
        assert!(batch.status.success(), "{}", text(&batch.stderr));
        let want: Vec<String> = text(&batch.stdout).lines().map(str::to_owned).collect();
        assert_eq!(want.len(), queries.len(), "{material}");

        // Through a pipe, one line at a time, each answer awaited.
        let mut child = Command::new(EXE)
            .args(args)
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .spawn()
            .expect("spawn strata");
        let mut stdin = child.stdin.take().expect("stdin");
        let stdout = child.stdout.take().expect("stdout");
        let (tx, rx) = mpsc::channel();
        let reader = std::thread::spawn(move || {
            for line in BufReader::new(stdout).lines() {
                if tx.send(line.expect("read an answer")).is_err() {
                    break;
                }
            }
        });
        let mut got = Vec::new();
        for q in queries {
            writeln!(stdin, "{q}").expect("write a query");
            stdin.flush().expect("flush");
            match rx.recv_timeout(Duration::from_secs(30)) {
                Ok(answer) => got.push(answer),
                Err(_) => break,
            }
        }
        let answered = got.len();
        if answered < queries.len() {
            // Do not leave it waiting for input that will never come.
            let _ = child.kill();
        }
        drop(stdin);
        let status = child.wait().expect("wait for strata");
        reader.join().expect("reader");
        assert_eq!(
            answered,
            queries.len(),
            "{material}: query {} got no answer before the next was written",
            answered + 1
        );
        assert!(status.success(), "{material}: {status}");
        assert_eq!(
            got, want,
            "{material}: a pipe's answers differ from a file's"
        );
    }
}

/// A JSON material's invalid value is an error naming its layer and field,
/// as a TOML file's is.
#[test]
fn json_material_errors_name_the_layer_and_the_field() {
    let dir = scratch("input-json");
    let cases = [
        (
            r#"{"layers":[{"interface":{"kind":"dielectric","ior":"NaN"}},{"interface":{"kind":"diffuse","albedo":0.5}}]}"#,
            &["layers[0].interface", "\"NaN\"", "`ior`"][..],
        ),
        (
            r#"{"layers":[{"interface":{"kind":"dielectric","ior":1.5},"medium":{"thickness":"x","sigma_t":1}},{"interface":{"kind":"diffuse","albedo":0.5}}]}"#,
            &["layers[0].medium.thickness", "\"x\""][..],
        ),
        (
            r#"{"layers":[{"interface":{"kind":"dielectric","ior":1.5}},{"interface":{"kind":"diffuse","albedo":"x"}}]}"#,
            &["layers[1].interface", "`albedo`", "\"x\""][..],
        ),
    ];
    for (i, (json, needles)) in cases.iter().enumerate() {
        let path = dir.join(format!("bad{i}.json"));
        std::fs::write(&path, json).expect("write material");
        let m = path.to_string_lossy();
        let out = run(
            &["eval", "--material", &m],
            r#"{"wi":[0,0,1],"wo":[0,0,1]}"#,
        );
        assert_fails_with(&out, needles);
        assert_fails_with(&out, &["invalid JSON material"]);
    }
}

/// A table written as an array, in a material (JSON or TOML) or a query
/// line, is an error naming where; it was read field by field.
#[test]
fn tables_written_as_arrays_are_refused() {
    let dir = scratch("input-arrays");
    let files = [
        (
            "layer.json",
            r#"{"layers":[[{"kind":"diffuse","albedo":0.5}]]}"#,
            "layers[0]: invalid type: sequence, expected a layer",
        ),
        (
            "interface.json",
            r#"{"layers":[{"interface":["diffuse",0.5]}]}"#,
            "layers[0].interface: invalid type: sequence, expected an interface",
        ),
        (
            "interface.toml",
            "[[layers]]\ninterface = [\"diffuse\", 0.5]\n",
            "invalid type: sequence, expected an interface",
        ),
    ];
    for (name, body, want) in files {
        let path = dir.join(name);
        std::fs::write(&path, body).expect("write material");
        let m = path.to_string_lossy();
        let out = run(
            &["eval", "--material", &m],
            r#"{"wi":[0,0,1],"wo":[0,0,1]}"#,
        );
        assert_fails_with(&out, &[want]);
    }
    let m = example("clear_coat_lambertian.toml");
    let out = run(
        &["eval", "--material", &m, "--samples", "4"],
        "{\"wi\":[0,0,1],\"wo\":[0,0,1]}\n[[0,0,1],[0,0,1]]\n",
    );
    assert_fails_with(&out, &["stdin line 2", "invalid type: sequence"]);
    assert_eq!(
        text(&out.stdout).lines().count(),
        1,
        "the first line's answer"
    );
}

/// A query line's set that names a path twice is an error naming the path
/// and the line (the last value was taken); so is `strata sample --set`'s.
#[test]
fn a_set_path_given_twice_is_an_error() {
    let m = example("clear_coat_lambertian.toml");
    let lines = "{\"wi\":[0,0,1],\"wo\":[0,0,1],\"set\":{\"exterior_ior\":1.2}}\n\
                 {\"wi\":[0,0,1],\"wo\":[0,0,1],\"set\":{\"exterior_ior\":1.2,\"exterior_ior\":1.3}}\n";
    let out = run(&["eval", "--material", &m, "--samples", "4"], lines);
    assert_fails_with(&out, &["stdin line 2", "set `exterior_ior`: given twice"]);
    assert_eq!(
        text(&out.stdout).lines().count(),
        1,
        "the first line's answer"
    );
    let set = r#"{"layers[0].interface.ior":1.2,"layers[0].interface.ior":1.3}"#;
    let out = run(
        &[
            "sample",
            "--material",
            &m,
            "--wi",
            "0,0,1",
            "--count",
            "2",
            "--set",
            set,
        ],
        "",
    );
    assert_fails_with(
        &out,
        &["--set", "set `layers[0].interface.ior`: given twice"],
    );
}
