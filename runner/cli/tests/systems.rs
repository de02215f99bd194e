//! `runner simulate SYSTEM` and `runner sweep SYSTEM` on small SSP systems written here, of the
//! Reference FMUs' Feedthrough (outputs equal inputs at once: direct feedthrough, declared in its
//! ModelStructure) and the C test FMU faulty.c: unit conversion, parameter files and mappings,
//! nested systems, the two masters, algebraic loops, failing components and the errors of bad
//! systems. The values are worked out by hand from Feedthrough's identity.

mod common;

use std::path::{Path, PathBuf};

use common::{column, fails, faulty_fmu, ok, read_csv, runner, system};

fn feedthrough() -> Option<PathBuf> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/reference-fmus/fmi2/Feedthrough.fmu");
    path.is_file().then_some(path)
}

fn component(name: &str, connectors: &str, extra: &str) -> String {
    format!(
        r#"<ssd:Component name="{name}" source="resources/ft.fmu"><ssd:Connectors>{connectors}</ssd:Connectors>{extra}</ssd:Component>"#
    )
}

const REAL_IN: &str = r#"<ssd:Connector name="Float64_continuous_input" kind="input"><ssc:Real/></ssd:Connector>"#;
const REAL_OUT: &str = r#"<ssd:Connector name="Float64_continuous_output" kind="output"><ssc:Real/></ssd:Connector>"#;

fn connection(from: &str, to: &str) -> String {
    format!(
        r#"<ssd:Connection startElement="{from}" startConnector="Float64_continuous_output" endElement="{to}" endConnector="Float64_continuous_input"/>"#
    )
}

/// km/h into m/s: 36 km/h set on a's input reach b as 10 m/s (Feedthrough copies input to
/// output), through a connection whose units differ; with suppressUnitConversion, 36.
#[test]
fn connections_convert_units_unless_suppressed() {
    let Some(ft) = feedthrough() else { return };
    let dir = tempfile::tempdir().unwrap();
    let units = r#"<ssd:Units><ssc:Unit name="km/h"><ssc:BaseUnit m="1" s="-1" factor="0.2777777777777778"/></ssc:Unit><ssc:Unit name="m/s"><ssc:BaseUnit m="1" s="-1"/></ssc:Unit></ssd:Units>"#;
    for (suppress, expected) in [("false", 10.0), ("true", 36.0)] {
        let ssd = format!(
            r#"<ssd:System name="s"><ssd:Elements>{}{}</ssd:Elements><ssd:Connections><ssd:Connection startElement="a" startConnector="Float64_continuous_output" endElement="b" endConnector="Float64_continuous_input" suppressUnitConversion="{suppress}"/></ssd:Connections></ssd:System>{units}"#,
            component("a", r#"<ssd:Connector name="Float64_continuous_output" kind="output"><ssc:Real unit="km/h"/></ssd:Connector>"#, ""),
            component("b", r#"<ssd:Connector name="Float64_continuous_input" kind="input"><ssc:Real unit="m/s"/></ssd:Connector>"#, ""),
        );
        let root = system(dir.path(), &format!("units{suppress}"), &ssd, &[("ft.fmu", &ft)], &[]);
        let out = dir.path().join(format!("u{suppress}.csv"));
        ok(runner(
            dir.path(),
            &[
                "simulate",
                root.to_str().unwrap(),
                "--stop-time",
                "0.3",
                "--output-interval",
                "0.1",
                "--set",
                "a.Float64_continuous_input=36",
                "--out",
                out.to_str().unwrap(),
            ],
        ));
        let (header, rows) = read_csv(&out);
        let b = column(&header, &rows, "b.Float64_continuous_output");
        assert!(b.iter().all(|&x| (x - expected).abs() < 1e-12), "suppress={suppress}: {b:?}");
    }
}

/// A chain a -> b -> sub.c: a ParameterBinding from a .ssv file through a .ssm mapping sets a's
/// input (`speed` in the file, mapped with a factor 2), and c sits in a nested system reached
/// through its connector `in`. Initialization passes values along the chain before the first
/// step, so under either master every output at every point is 2 * 5 = 10, and the Integer
/// parameter of the file reaches a's Int32_input (7).
#[test]
fn parameter_files_mappings_and_nested_systems() {
    let Some(ft) = feedthrough() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ssv = r#"<ssv:ParameterSet xmlns:ssv="http://ssp-standard.org/SSP1/SystemStructureParameterValues" version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="speed"><ssv:Real value="5"/></ssv:Parameter><ssv:Parameter name="Int32_input"><ssv:Integer value="7"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet>"#;
    let ssm = r#"<ssm:ParameterMapping xmlns:ssm="http://ssp-standard.org/SSP1/SystemStructureParameterMapping" xmlns:ssc="http://ssp-standard.org/SSP1/SystemStructureCommon" version="1.0"><ssm:MappingEntry source="speed" target="Float64_continuous_input"><ssc:LinearTransformation factor="2" offset="0"/></ssm:MappingEntry></ssm:ParameterMapping>"#;
    let binding = r#"<ssd:ParameterBindings><ssd:ParameterBinding source="a.ssv"><ssd:ParameterMapping source="a.ssm"/></ssd:ParameterBinding></ssd:ParameterBindings>"#;
    let nested = format!(
        r#"<ssd:System name="sub"><ssd:Connectors><ssd:Connector name="in" kind="input"><ssc:Real/></ssd:Connector></ssd:Connectors><ssd:Elements>{}</ssd:Elements><ssd:Connections><ssd:Connection startConnector="in" endElement="c" endConnector="Float64_continuous_input"/></ssd:Connections></ssd:System>"#,
        component("c", &format!("{REAL_IN}{REAL_OUT}"), "")
    );
    let ssd = format!(
        r#"<ssd:System name="s"><ssd:Elements>{}{}{nested}</ssd:Elements><ssd:Connections>{}<ssd:Connection startElement="b" startConnector="Float64_continuous_output" endElement="sub" endConnector="in"/></ssd:Connections></ssd:System>"#,
        component("a", &format!("{REAL_IN}{REAL_OUT}"), binding),
        component("b", &format!("{REAL_IN}{REAL_OUT}"), ""),
        connection("a", "b"),
    );
    let root = system(dir.path(), "chain", &ssd, &[("ft.fmu", &ft)], &[("a.ssv", ssv), ("a.ssm", ssm)]);
    for master in ["jacobi", "gauss-seidel"] {
        let out = dir.path().join(format!("{master}.csv"));
        ok(runner(
            dir.path(),
            &[
                "simulate",
                root.to_str().unwrap(),
                "--stop-time",
                "0.2",
                "--output-interval",
                "0.1",
                "--master",
                master,
                "--out",
                out.to_str().unwrap(),
            ],
        ));
        let (header, rows) = read_csv(&out);
        for name in ["a.Float64_continuous_output", "b.Float64_continuous_output", "sub.c.Float64_continuous_output"] {
            assert_eq!(column(&header, &rows, name), [10.0, 10.0, 10.0], "{master}: {name}");
        }
        assert_eq!(column(&header, &rows, "a.Int32_output"), [7.0, 7.0, 7.0]);
    }
}

/// Two Feedthroughs feeding each other: an algebraic loop. Gauss-Seidel refuses it naming the
/// loop; Jacobi warns and runs it with its one-step delay.
#[test]
fn algebraic_loops_are_reported() {
    let Some(ft) = feedthrough() else { return };
    let dir = tempfile::tempdir().unwrap();
    let ssd = format!(
        r#"<ssd:System name="s"><ssd:Elements>{}{}</ssd:Elements><ssd:Connections>{}{}</ssd:Connections></ssd:System>"#,
        component("a", &format!("{REAL_IN}{REAL_OUT}"), ""),
        component("b", &format!("{REAL_IN}{REAL_OUT}"), ""),
        connection("a", "b"),
        connection("b", "a"),
    );
    let root = system(dir.path(), "loop", &ssd, &[("ft.fmu", &ft)], &[]);
    let path = root.to_str().unwrap();
    let err = fails(runner(dir.path(), &["simulate", path, "--master", "gauss-seidel", "--stop-time", "0.1"]));
    assert!(
        err.contains("algebraic loop of direct feedthrough")
            && err.contains("a.Float64_continuous_input")
            && err.contains("b.Float64_continuous_output"),
        "{err}"
    );
    let done = runner(dir.path(), &["simulate", path, "--stop-time", "0.1", "--out", dir.path().join("l.csv").to_str().unwrap()]);
    assert!(done.status.success());
    assert!(common::stderr(&done).contains("warning: algebraic loop"), "{}", common::stderr(&done));
}

/// faulty.c's fault 7 makes fmi2DoStep return fmi2Error from t = 0.5: the system stops naming
/// the component, the time and the call, and keeps the rows before it; a sweep records it in the
/// status column of that point only.
#[test]
fn a_failing_component_stops_the_system_and_keeps_the_rows() {
    let dir = tempfile::tempdir().unwrap();
    let fmu = faulty_fmu(dir.path(), "faulty.fmu", false, &[]);
    let comp = |name: &str, fault: i32| {
        format!(
            r#"<ssd:Component name="{name}" source="resources/faulty.fmu"><ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="fault"><ssv:Integer value="{fault}"/></ssv:Parameter><ssv:Parameter name="fault_time"><ssv:Real value="0.5"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings></ssd:Component>"#
        )
    };
    let ssd = format!(r#"<ssd:System name="s"><ssd:Elements>{}{}</ssd:Elements></ssd:System>"#, comp("good", 0), comp("bad", 7));
    let root = system(dir.path(), "faulty", &ssd, &[("faulty.fmu", &fmu)], &[]);
    let out = dir.path().join("f.csv");
    let err = fails(runner(dir.path(), &["simulate", root.to_str().unwrap(), "--output-interval", "0.1", "--out", out.to_str().unwrap()]));
    assert!(err.contains("component 'bad' at t = 0.5") && err.contains("fmi2DoStep") && err.contains("rows before it"), "{err}");
    let (header, rows) = read_csv(&out);
    assert_eq!(column(&header, &rows, "time"), [0.0, 0.1, 0.2, 0.30000000000000004, 0.4, 0.5]);
    // The sweep: fault_time swept, one point fails inside the run, the other never reaches it.
    let sweep = dir.path().join("s.csv");
    let done = runner(
        dir.path(),
        &[
            "sweep",
            root.to_str().unwrap(),
            "--param",
            "bad.fault_time=0.5,2",
            "--metric",
            "end=final(good.x)",
            "--threads",
            "2",
            "--out",
            sweep.to_str().unwrap(),
        ],
    );
    assert!(!done.status.success());
    let (header, rows) = read_csv(&sweep);
    let status = header.iter().position(|h| h == "status").unwrap();
    assert!(rows[0][status].contains("failed: component 'bad' at t = 0.5"), "{:?}", rows[0]);
    assert_eq!(rows[1][status], "ok");
    assert!((rows[1][1].parse::<f64>().unwrap() - (-1.0f64).exp()).abs() < 1e-12, "x = exp(-k t) at t = 1: {:?}", rows[1]);
    // Metrics that need one FMU (a frequency from its parameters, its linearized modes) are
    // refused by name before any point runs.
    for (metric, why) in [("a=amplitude(good.x, 0.5, 2*pi*k)", "amplitude(...)"), ("z=damping(1)", "damping(N)")] {
        let err = fails(runner(dir.path(), &["sweep", root.to_str().unwrap(), "--param", "bad.fault_time=2", "--metric", metric]));
        assert!(err.contains(why) && err.contains("not of a system"), "{err}");
    }
}

/// Bad systems are refused with the file, the line and what is wrong.
#[test]
fn bad_systems_are_explained() {
    let Some(ft) = feedthrough() else { return };
    let dir = tempfile::tempdir().unwrap();
    let good = component("a", &format!("{REAL_IN}{REAL_OUT}"), "");
    let cases = [
        (format!(r#"<ssd:System name="s"><ssd:Elements>{good}</ssd:Elements><ssd:Connections><ssd:Connection startElement="a" startConnector="nope" endElement="a" endConnector="Float64_continuous_input"/></ssd:Connections></ssd:System>"#), "the component has no such connector"),
        (r#"<ssd:System name="s"><ssd:Elements><ssd:Component name="x" source="resources/missing.fmu"/></ssd:Elements></ssd:System>"#.to_owned(), "component 'x': its FMU resources/missing.fmu is not in the system"),
        (r#"<ssd:System name="s"><ssd:Elements><ssd:Component name="x" source="sub.ssd" type="application/x-ssp-definition"/></ssd:Elements></ssd:System>"#.to_owned(), "only FMUs"),
        (format!(r#"<ssd:System name="s"><ssd:Elements>{}</ssd:Elements></ssd:System>"#, component("a", "", r#"<ssd:ParameterBindings><ssd:ParameterBinding><ssd:ParameterValues><ssv:ParameterSet version="1.0" name="p"><ssv:Parameters><ssv:Parameter name="no_such"><ssv:Real value="1"/></ssv:Parameter></ssv:Parameters></ssv:ParameterSet></ssd:ParameterValues></ssd:ParameterBinding></ssd:ParameterBindings>"#)), "parameter a.no_such"),
        (format!(r#"<ssd:System name="s"><ssd:Elements>{good}</ssd:Elements>"#), "not well-formed"),
    ];
    for (k, (ssd, expected)) in cases.iter().enumerate() {
        let root = system(dir.path(), &format!("bad{k}"), ssd, &[("ft.fmu", &ft)], &[]);
        let err = fails(runner(dir.path(), &["simulate", root.to_str().unwrap(), "--stop-time", "0.1"]));
        assert!(err.contains(expected), "case {k}: {err}");
    }
    let root = system(
        dir.path(),
        "ok",
        &format!(r#"<ssd:System name="s"><ssd:Elements>{good}</ssd:Elements></ssd:System>"#),
        &[("ft.fmu", &ft)],
        &[],
    );
    let err = fails(runner(dir.path(), &["simulate", root.to_str().unwrap(), "--set", "zz.x=1"]));
    assert!(err.contains("'zz.x' names no component of the system"), "{err}");
    let err = fails(runner(dir.path(), &["simulate", root.to_str().unwrap(), "--master", "newton"]));
    assert!(err.contains("choose jacobi or gauss-seidel"), "{err}");
    // The Reference FMUs' Feedthrough gives no output derivatives: asked for polynomials, the
    // runner says every input holds, and runs.
    let held = runner(dir.path(), &["simulate", root.to_str().unwrap(), "--coupling", "polynomial", "--stop-time", "0.1"]);
    assert!(held.status.success(), "{}", String::from_utf8_lossy(&held.stderr));
    assert!(String::from_utf8_lossy(&held.stderr).contains("no connection of the system can pass a polynomial"));
    let err = fails(runner(dir.path(), &["simulate", root.to_str().unwrap(), "--coupling", "spline"]));
    assert!(err.contains("--coupling 'spline': choose hold or polynomial"), "{err}");
}

/// A sweep reads only its metrics' columns and the outputs that feed connections (the
/// connection plan of fmi-systems), yet gets what `simulate` records: a -> b (a Real in km/h to
/// m/s, an Int32 and a Boolean, so b takes one batched Real set and two single ones) -> c (a
/// Real). Feedthrough copies inputs to outputs, so with a's inputs 36 km/h, 3 and true, c's
/// Real output ends at 10 m/s and b's Int32 and Boolean outputs at 3 and 1; each sweep metric
/// equals the simulated CSV's last row to the bit (72 km/h gives 20 m/s).
#[test]
fn a_sweep_reads_only_what_it_needs_and_agrees_with_simulate() {
    let Some(ft) = feedthrough() else { return };
    let dir = tempfile::tempdir().unwrap();
    let units = r#"<ssd:Units><ssc:Unit name="km/h"><ssc:BaseUnit m="1" s="-1" factor="0.2777777777777778"/></ssc:Unit><ssc:Unit name="m/s"><ssc:BaseUnit m="1" s="-1"/></ssc:Unit></ssd:Units>"#;
    let connector = |name: &str, kind: &str, ty: &str| format!(r#"<ssd:Connector name="{name}" kind="{kind}">{ty}</ssd:Connector>"#);
    let (int, boolean) = ("<ssc:Integer/>", "<ssc:Boolean/>");
    let a = component(
        "a",
        &[
            connector("Float64_continuous_output", "output", r#"<ssc:Real unit="km/h"/>"#),
            connector("Int32_output", "output", int),
            connector("Boolean_output", "output", boolean),
        ]
        .concat(),
        "",
    );
    let b = component(
        "b",
        &[
            connector("Float64_continuous_input", "input", r#"<ssc:Real unit="m/s"/>"#),
            connector("Int32_input", "input", int),
            connector("Boolean_input", "input", boolean),
            connector("Float64_continuous_output", "output", r#"<ssc:Real unit="m/s"/>"#),
            connector("Int32_output", "output", int),
            connector("Boolean_output", "output", boolean),
        ]
        .concat(),
        "",
    );
    let c = component("c", &format!("{REAL_IN}{REAL_OUT}"), "");
    let link = |from: &str, to: &str, name: &str, to_name: &str| {
        format!(r#"<ssd:Connection startElement="{from}" startConnector="{name}" endElement="{to}" endConnector="{to_name}"/>"#)
    };
    let ssd = format!(
        r#"<ssd:System name="s"><ssd:Elements>{a}{b}{c}</ssd:Elements><ssd:Connections>{}{}{}{}</ssd:Connections></ssd:System>{units}"#,
        link("a", "b", "Float64_continuous_output", "Float64_continuous_input"),
        link("a", "b", "Int32_output", "Int32_input"),
        link("a", "b", "Boolean_output", "Boolean_input"),
        connection("b", "c"),
    );
    let root = system(dir.path(), "plan", &ssd, &[("ft.fmu", &ft)], &[]);
    let grid = ["--stop-time", "0.5", "--output-interval", "0.1"];
    let sets = ["--set", "a.Int32_input=3", "--set", "a.Boolean_input=true"];
    let csv = dir.path().join("sim.csv");
    let root = root.to_str().unwrap();
    ok(runner(
        dir.path(),
        &[&["simulate", root, "--set", "a.Float64_continuous_input=36"][..], &grid, &sets, &["--out", csv.to_str().unwrap()]].concat(),
    ));
    let (header, rows) = read_csv(&csv);
    let last = |name: &str| *column(&header, &rows, name).last().unwrap();
    assert_eq!((last("c.Float64_continuous_output"), last("b.Int32_output"), last("b.Boolean_output")), (10.0, 3.0, 1.0));
    let sweep = dir.path().join("sweep.csv");
    let metrics = [
        "--metric",
        "v=final(c.Float64_continuous_output)",
        "--metric",
        "i=final(b.Int32_output)",
        "--metric",
        "b=final(b.Boolean_output)",
    ];
    ok(runner(
        dir.path(),
        &[
            &["sweep", root, "--param", "a.Float64_continuous_input=36,72", "--threads", "2"][..],
            &grid,
            &sets,
            &metrics,
            &["--out", sweep.to_str().unwrap()],
        ]
        .concat(),
    ));
    let (header, rows) = read_csv(&sweep);
    assert_eq!(column(&header, &rows, "v"), [last("c.Float64_continuous_output"), 20.0]);
    assert_eq!(column(&header, &rows, "i"), [3.0, 3.0]);
    assert_eq!(column(&header, &rows, "b"), [1.0, 1.0]);
}

/// `--input-file` drives a system's unconnected inputs, its columns named COMPONENT.INPUT: a's
/// columns equal a run of the FMU alone with the same table (whose input handling tests/fmpy
/// checks against fmpy's) to the bit, b follows a through the connection, and a sweep sees the
/// table too. The table's step is on a communication point: between points it would take effect
/// at the next one in the system, where a single FMU shortens its step onto it. A connected input
/// or an unknown component in the table is refused by name.
#[test]
fn input_files_drive_unconnected_inputs() {
    let Some(ft) = feedthrough() else { return };
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (component("a", &format!("{REAL_IN}{REAL_OUT}"), ""), component("b", &format!("{REAL_IN}{REAL_OUT}"), ""));
    let ssd = format!(
        r#"<ssd:System name="s"><ssd:Elements>{a}{b}</ssd:Elements><ssd:Connections>{}</ssd:Connections></ssd:System>"#,
        connection("a", "b")
    );
    let root = system(dir.path(), "inputs", &ssd, &[("ft.fmu", &ft)], &[]);
    let root = root.to_str().unwrap();
    // A ramp, a step at 0.5 (a time given twice) and an Integer held between rows.
    let rows = "0,0,1\n0.5,1,1\n0.5,3,4\n1,2,4\n";
    let (table, alone) = (dir.path().join("system_inputs.csv"), dir.path().join("inputs.csv"));
    std::fs::write(&table, format!("time,a.Float64_continuous_input,a.Int32_input\n{rows}")).unwrap();
    std::fs::write(&alone, format!("time,Float64_continuous_input,Int32_input\n{rows}")).unwrap();
    let grid = ["--stop-time", "1", "--output-interval", "0.1"];
    let (sys_csv, one_csv) = (dir.path().join("system.csv"), dir.path().join("one.csv"));
    let input = ["--input-file", table.to_str().unwrap()];
    ok(runner(dir.path(), &[&["simulate", root][..], &grid, &input, &["--out", sys_csv.to_str().unwrap()]].concat()));
    let ft = ft.to_str().unwrap();
    ok(runner(
        dir.path(),
        &[&["simulate", ft, "--input-file", alone.to_str().unwrap()][..], &grid, &["--out", one_csv.to_str().unwrap()]].concat(),
    ));
    let (sys_header, sys_rows) = read_csv(&sys_csv);
    let (one_header, one_rows) = read_csv(&one_csv);
    for name in ["Float64_continuous_output", "Int32_output"] {
        let system = column(&sys_header, &sys_rows, &format!("a.{name}"));
        assert_eq!(system, column(&one_header, &one_rows, name), "a.{name}");
    }
    let ramp = column(&sys_header, &sys_rows, "a.Float64_continuous_output");
    assert!(ramp.iter().any(|&x| x != 0.0) && ramp.contains(&3.0), "the table did not reach a: {ramp:?}");
    // b's input is a's output at each point (Jacobi), so b's output is a's, one point later.
    let b_out = column(&sys_header, &sys_rows, "b.Float64_continuous_output");
    assert_eq!(&b_out[2..], &ramp[1..ramp.len() - 1]);
    // A sweep sees the table: the final value after the step is the table's last, 2.
    let sweep = dir.path().join("sweep.csv");
    ok(runner(
        dir.path(),
        &[
            &["sweep", root, "--param", "b.Int32_input=1,2", "--metric", "v=final(a.Float64_continuous_output)"][..],
            &grid,
            &input,
            &["--out", sweep.to_str().unwrap()],
        ]
        .concat(),
    ));
    let (header, rows) = read_csv(&sweep);
    assert_eq!(column(&header, &rows, "v"), vec![*ramp.last().unwrap(); 2]);
    for (columns, expected) in [
        (
            "time,b.Float64_continuous_input\n0,1\n",
            "input file column 'b.Float64_continuous_input': the system connects that input to a.Float64_continuous_output",
        ),
        ("time,zz.u\n0,1\n", "input file column 'zz.u': 'zz.u' names no component of the system"),
        ("time,a.Float64_continuous_output\n0,1\n", "not an input"),
    ] {
        std::fs::write(&table, columns).unwrap();
        let err = fails(runner(dir.path(), &[&["simulate", root][..], &grid, &input].concat()));
        assert!(err.contains(expected), "{err}");
    }
}
