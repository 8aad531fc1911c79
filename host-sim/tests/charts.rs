//! What the charts show a reader, read from the SVG text the commands write: legends whose
//! entries each have a swatch of their own and name every curve, tick labels that never read
//! `-0`, an axis that shows millimetres beside metres, the run's moments marked.

mod support;

use std::time::Duration;

use support::{golden_log, run, scratch_dir};

const RUN_TIME: Duration = Duration::from_secs(120);

fn plant(name: &str) -> String {
    format!("{}/plants/{name}", env!("CARGO_MANIFEST_DIR"))
}

/// Runs `host-sim ARGS --plot FILE.svg` in a scratch directory named `name` and returns the
/// chart's text elements.
fn chart_texts(name: &str, args: &[&str]) -> (Vec<String>, String) {
    let svg = scratch_dir(name).join("chart.svg");
    let mut all: Vec<&str> = args.to_vec();
    all.extend(["--plot", svg.to_str().expect("UTF-8 path")]);
    let outcome = run(&all, RUN_TIME);
    assert!(matches!(outcome.code(), Some(0 | 1)), "{outcome:#?}");
    let chart = std::fs::read_to_string(&svg).expect("the chart");
    (texts(&chart), chart)
}

/// The contents of every `<text>` element.
fn texts(svg: &str) -> Vec<String> {
    svg.split("<text")
        .skip(1)
        .filter_map(|element| {
            let (_, rest) = element.split_once('>')?;
            let (content, _) = rest.split_once("</text>")?;
            let content = content
                .trim()
                .replace("&apos;", "'")
                .replace("&quot;", "\"")
                .replace("&lt;", "<")
                .replace("&gt;", ">")
                .replace("&amp;", "&");
            Some(content)
        })
        .collect()
}

/// No tick label reads as a negative zero.
fn assert_no_negative_zero(texts: &[String]) {
    for text in texts {
        let magnitude = text.trim_start_matches(['-', '−']);
        let zero = !magnitude.is_empty() && magnitude.chars().all(|c| c == '0' || c == '.');
        assert!(!(zero && magnitude != text), "tick label {text:?}");
    }
}

fn count(texts: &[String], wanted: &str) -> usize {
    texts.iter().filter(|text| *text == wanted).count()
}

#[test]
fn the_sweep_legend_names_each_colour_and_each_curve_once() {
    let (texts, _) = chart_texts("chart-sweep", &["sweep"]);
    for entry in [
        "a_max = 100 m/s²",
        "a_max = 150 m/s²",
        "a_max = 200 m/s²",
        "simulated",
        "non-quasi-static (Eq. 15/18)",
        "quasi-static (Eq. 9)",
    ] {
        assert_eq!(count(&texts, entry), 1, "{entry}: {texts:?}");
    }
    assert_eq!(
        texts.iter().filter(|text| text.contains("Eq.")).count(),
        2,
        "{texts:?}"
    );
    assert_no_negative_zero(&texts);
}

#[test]
fn the_drift_axis_reads_millimetres_and_metres_alike() {
    let (texts, _) = chart_texts("chart-drift", &["drift"]);
    for tick in ["−10", "−1", "0", "1", "10", "100", "1000"] {
        assert_eq!(count(&texts, tick), 1, "{tick}: {texts:?}");
    }
    assert_eq!(count(&texts, "500"), 0, "a linear axis: {texts:?}");
    assert_no_negative_zero(&texts);
}

#[test]
fn the_viscosity_chart_names_only_what_it_draws_and_reads_zero_as_zero() {
    let (texts, _) = chart_texts("chart-viscosity", &["viscosity"]);
    assert!(
        !texts.iter().any(|text| text.contains("sticks")),
        "{texts:?}"
    );
    assert!(texts.iter().any(|text| text == "0.00"), "{texts:?}");
    assert_no_negative_zero(&texts);
}

#[test]
fn the_closed_loop_chart_keeps_its_legends_short_and_draws_the_levels_as_dots() {
    let (texts, chart) = chart_texts(
        "chart-closed-loop",
        &[
            "closed-loop",
            "--plant",
            &plant("realistic.toml"),
            "--cycles",
            "200",
        ],
    );
    assert_eq!(count(&texts, "±50 µm"), 1, "{texts:?}");
    for text in texts.iter().skip(1) {
        assert!(
            text.chars().count() <= 65,
            "a legend this long hides the trace: {text}"
        );
    }
    // The bias and the two trims of every cycle from the release on, as dots.
    assert!(chart.matches("<circle").count() >= 3 * 200, "too few dots");
    assert_no_negative_zero(&texts);
}

#[test]
fn the_firmware_in_the_loop_chart_marks_the_start_the_new_duty_and_the_stop() {
    let log = golden_log();
    let input = log.to_str().expect("UTF-8 path");
    let (texts, _) = chart_texts("chart-hil", &["hil", "--input", input]);
    for entry in [
        "start at 0.040 s",
        "d = 0.586 → 0.606 at 0.222 s",
        "stop at 0.416 s",
    ] {
        assert_eq!(
            count(&texts, entry),
            2,
            "{entry}, in both panels: {texts:?}"
        );
    }
    assert_eq!(count(&texts, "plate (µm/s)"), 1, "{texts:?}");
    assert_no_negative_zero(&texts);

    let (texts, _) = chart_texts(
        "chart-hil-plant",
        &["hil", "--input", input, "--plant", &plant("realistic.toml")],
    );
    assert_eq!(count(&texts, "start at 0.040 s"), 2, "{texts:?}");
    assert_eq!(count(&texts, "end stop at 0.111 s"), 2, "{texts:?}");
    assert!(
        !texts.iter().any(|text| text.contains("0.606")),
        "a moment after the plate's run: {texts:?}"
    );
    assert_eq!(count(&texts, "plate position (mm)"), 1, "{texts:?}");
    assert_no_negative_zero(&texts);
}

#[test]
fn the_texts_of_a_chart_are_read_whole() {
    let svg = "<svg><text x=\"1\">\na &amp; b&apos;s\n</text><text y=\"2\">−10</text></svg>";
    assert_eq!(texts(svg), ["a & b's", "−10"]);
}

#[test]
fn the_real_plate_s_trace_marks_its_end_stop_and_draws_its_position_on_its_own_axis() {
    let (texts, _) = chart_texts(
        "chart-trace-plant",
        &["trace", "--plant", &plant("realistic.toml")],
    );
    assert_eq!(count(&texts, "end stop at 0.065 s"), 2, "{texts:?}");
    assert_eq!(count(&texts, "plate position (mm)"), 1, "{texts:?}");
    assert_no_negative_zero(&texts);
}

#[test]
fn the_closed_loop_chart_marks_a_live_duty_change_from_the_release_on() {
    let (texts, _) = chart_texts(
        "chart-closed-loop-change",
        &[
            "closed-loop",
            "--plant",
            &plant("realistic.toml"),
            "--cycles",
            "200",
            "--change-duty-at",
            "100",
            "--to-duty",
            "0.596",
        ],
    );
    let marks = texts
        .iter()
        .filter(|text| text.starts_with("d = 0.586 → 0.596 at "))
        .count();
    assert_eq!(marks, 3, "the three panels from the release on: {texts:?}");
}
