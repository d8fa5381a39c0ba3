//! `report::plot` and `report::csv`: every plot kind writes a valid SVG (root element, title, series
//! names) and a PNG of the requested size that is not one flat colour; two writes give the same bytes;
//! bad input is an error that writes nothing. CSV round trip and determinism.
//!
//! Set `ATLASTREE_PLOT_DIR=/some/dir` to keep the plots there for a look (the directory must exist).

use atlastree::report::ReportError;
use atlastree::report::csv::{Cell, CsvWriter, read_csv, write_csv};
use atlastree::report::metrics::Histogram;
use atlastree::report::plot::{
    BarSeries, Better, HeatMap, LabelledPoint, PlotFiles, PlotOptions, PointLabels, ScatterSeries,
    Series, bar_chart, heat_map, histogram_chart, line_chart, scatter_pareto,
};
use std::path::{Path, PathBuf};

/// Where the plots go: `ATLASTREE_PLOT_DIR` if set, else a temp dir (kept alive by the returned guard).
fn out_dir() -> (PathBuf, Option<tempfile::TempDir>) {
    match std::env::var_os("ATLASTREE_PLOT_DIR") {
        Some(d) => (PathBuf::from(d), None),
        None => {
            let t = tempfile::tempdir().unwrap();
            (t.path().to_path_buf(), Some(t))
        }
    }
}

/// Checks both files of a plot and returns the SVG text.
fn check_files(files: &PlotFiles, opts: &PlotOptions, names: &[&str]) -> String {
    let svg = std::fs::read_to_string(&files.svg).unwrap();
    assert!(
        svg.starts_with("<svg"),
        "{}: {}",
        files.svg.display(),
        &svg[..40.min(svg.len())]
    );
    assert!(svg.trim_end().ends_with("</svg>"));
    assert!(svg.contains(&format!("width=\"{}\"", opts.width)));
    assert!(svg.contains(&opts.title), "title {:?} missing", opts.title);
    for n in names {
        assert!(
            svg.contains(n),
            "{:?} missing from {}",
            n,
            files.svg.display()
        );
    }

    let decoder = png::Decoder::new(std::io::BufReader::new(
        std::fs::File::open(&files.png).unwrap(),
    ));
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!((info.width, info.height), (opts.width, opts.height));
    assert_eq!(info.color_type, png::ColorType::Rgb);
    let px = &buf[..info.buffer_size()];
    let mut colours: Vec<[u8; 3]> = px.chunks_exact(3).map(|p| [p[0], p[1], p[2]]).collect();
    colours.sort_unstable();
    colours.dedup();
    assert!(
        colours.len() > 16,
        "{}: only {} colours",
        files.png.display(),
        colours.len()
    );
    // Mostly white background, but a real share of ink.
    let white = px.chunks_exact(3).filter(|p| *p == [255, 255, 255]).count();
    let total = px.len() / 3;
    assert!(
        white > total / 4 && white < total * 99 / 100,
        "white {white} of {total}"
    );
    svg
}

/// Runs `plot` twice into `dir/NAME` and `dir/NAME-again`; both SVGs and PNGs must be byte-identical.
fn twice(dir: &Path, name: &str, mut plot: impl FnMut(&Path) -> PlotFiles) -> PlotFiles {
    let a = plot(&dir.join(name));
    let b = plot(&dir.join(format!("{name}-again")));
    assert_eq!(
        std::fs::read(&a.svg).unwrap(),
        std::fs::read(&b.svg).unwrap(),
        "{name}.svg"
    );
    assert_eq!(
        std::fs::read(&a.png).unwrap(),
        std::fs::read(&b.png).unwrap(),
        "{name}.png"
    );
    std::fs::remove_file(b.svg).unwrap();
    std::fs::remove_file(b.png).unwrap();
    a
}

#[test]
fn line_chart_writes_svg_and_png() {
    let (dir, _guard) = out_dir();
    let series: Vec<Series> = [40.0, 80.0, 160.0]
        .iter()
        .map(|&k| {
            let pts = (0..300)
                .map(|f| {
                    let t = f as f64;
                    // A gap (NaN) in the middle of the first series.
                    let y = if k == 40.0 && (100..110).contains(&f) {
                        f64::NAN
                    } else {
                        (0.3 * (t / 40.0).sin().abs() + 0.02) * 40.0 / k
                    };
                    (t, y)
                })
                .collect();
            Series::new(format!("k = {k}"), pts)
        })
        .collect();
    let opts = PlotOptions::new("Coarser screen share per frame", "frame", "coarser share");
    let files = twice(&dir, "line", |p| line_chart(p, &opts, &series).unwrap());
    assert_eq!(files.svg, dir.join("line.svg"));
    check_files(
        &files,
        &opts,
        &["k = 40", "k = 80", "k = 160", "frame", "coarser share"],
    );
}

#[test]
fn line_chart_on_log_axes_skips_non_positive_points() {
    let (dir, _guard) = out_dir();
    let ratios = [0.25, 0.5, 1.0, 2.0];
    let series = vec![
        Series::new(
            "PSNR box",
            ratios.iter().map(|&r| (r, 30.0 + 4.0 * r)).collect(),
        ),
        Series::new(
            "PSNR Lanczos",
            ratios
                .iter()
                .map(|&r| (r, 31.0 + 4.5 * r))
                .chain([(0.0, 50.0)])
                .collect(),
        ),
    ];
    let mut opts = PlotOptions::new("PSNR by texel ratio", "texels per pixel", "PSNR (dB)");
    opts.log_x = true;
    opts.width = 640;
    opts.height = 400;
    let files = twice(&dir, "line-logx", |p| {
        line_chart(p, &opts, &series).unwrap()
    });
    let svg = check_files(&files, &opts, &["PSNR box", "PSNR Lanczos"]);
    // Ticks at powers of two.
    for t in ["\n0.25\n", "\n0.5\n", "\n1\n", "\n2\n"] {
        assert!(svg.contains(t), "tick {t} missing");
    }
}

#[test]
fn heat_map_writes_labels_values_and_colour_bar() {
    let (dir, _guard) = out_dir();
    let caps = ["40", "80", "160", "320"];
    let bws = ["5 MB/s", "50 MB/s", "500 MB/s"];
    let mut values = Vec::new();
    for (r, _) in caps.iter().enumerate() {
        for (c, _) in bws.iter().enumerate() {
            values.push(0.4 / (1.0 + r as f64 * 1.5 + c as f64 * 2.0));
        }
    }
    values[1] = f64::NAN; // a missing cell
    let map = HeatMap {
        row_labels: caps.iter().map(|s| s.to_string()).collect(),
        col_labels: bws.iter().map(|s| s.to_string()).collect(),
        values,
        decimals: 3,
        value_range: None,
        value_label: "mean coarser share".into(),
    };
    let opts = PlotOptions::new("Mean coarser share", "bandwidth", "capacity k (blocks)");
    let files = twice(&dir, "heat", |p| heat_map(p, &opts, &map).unwrap());
    check_files(
        &files,
        &opts,
        &[
            "5 MB/s",
            "500 MB/s",
            "320",
            "0.400",
            "mean coarser share",
            "–",
        ],
    );

    let bad = HeatMap {
        values: vec![1.0; 5],
        ..map
    };
    let err = heat_map(&dir.join("bad"), &opts, &bad).unwrap_err();
    assert!(matches!(err, ReportError::PlotInput { .. }), "{err}");
    assert!(!dir.join("bad.svg").exists() && !dir.join("bad.png").exists());
}

#[test]
fn scatter_marks_the_pareto_front() {
    let (dir, _guard) = out_dir();
    let pt = |x: f64, y: f64, label: &str| LabelledPoint {
        x,
        y,
        label: label.into(),
    };
    let groups = vec![
        ScatterSeries {
            name: "atlas 512".into(),
            points: vec![
                pt(2.0, 0.90, "r0.5"),
                pt(3.0, 0.95, "r1"),
                pt(5.0, 0.93, "r2"),
            ],
        },
        ScatterSeries {
            name: "atlas 2048".into(),
            points: vec![
                pt(1.5, 0.80, "r0.25"),
                pt(4.0, 0.97, "r1"),
                pt(6.0, 0.99, "r2"),
            ],
        },
    ];
    let opts = PlotOptions::new("SSIM vs frame time", "frame time (ms)", "SSIM");
    let mut front = Vec::new();
    let files = twice(&dir, "pareto", |p| {
        let (f, fr) = scatter_pareto(p, &opts, &groups, Better::HigherY, PointLabels::All).unwrap();
        front = fr;
        f
    });
    assert_eq!(front, vec![(1, 0), (0, 0), (0, 1), (1, 1), (1, 2)]);
    check_files(&files, &opts, &["atlas 512", "atlas 2048", "r0.25", "r0.5"]);

    // Lower is better: the front flips to the cheapest point with the least error.
    let (_, front) = scatter_pareto(
        &dir.join("pareto-low"),
        &opts,
        &groups,
        Better::LowerY,
        PointLabels::Front,
    )
    .unwrap();
    assert_eq!(front, vec![(1, 0)]);
}

#[test]
fn histogram_and_bar_charts() {
    let (dir, _guard) = out_dir();
    let sharp: Vec<f32> = (0..4000)
        .map(|i| 2f32.powf((i % 97) as f32 / 97.0 * 5.0 - 1.5))
        .collect();
    let soft: Vec<f32> = (0..4000)
        .map(|i| 2f32.powf((i % 89) as f32 / 89.0 * 4.0 - 3.0))
        .collect();
    let (hs, hb) = (
        Histogram::log2(&sharp, -3, 3),
        Histogram::log2(&soft, -3, 3),
    );
    let opts = PlotOptions::new(
        "Texels per pixel",
        "texels per pixel (bin from)",
        "share of drawn pixels",
    );
    let files = twice(&dir, "hist", |p| {
        histogram_chart(
            p,
            &opts,
            &[("ratio 1".into(), &hs), ("ratio 0.25".into(), &hb)],
        )
        .unwrap()
    });
    check_files(&files, &opts, &["ratio 1", "ratio 0.25", "2⁻³", "≥2³"]);

    let other = Histogram::log2(&soft, -2, 3);
    let err = histogram_chart(
        &dir.join("mixed"),
        &opts,
        &[("a".into(), &hs), ("b".into(), &other)],
    )
    .unwrap_err();
    assert!(matches!(err, ReportError::PlotInput { .. }), "{err}");

    let cats: Vec<String> = ["select", "paging", "encode", "GPU"]
        .map(String::from)
        .to_vec();
    let bars = vec![BarSeries {
        name: "µs per frame".into(),
        values: vec![40.0, 12.0, 85.0, f64::NAN],
    }];
    let opts = PlotOptions::new("Frame cost", "stage", "µs");
    let files = twice(&dir, "bars", |p| bar_chart(p, &opts, &cats, &bars).unwrap());
    check_files(&files, &opts, &["select", "GPU", "µs per frame"]);
    let short = vec![BarSeries {
        name: "x".into(),
        values: vec![1.0],
    }];
    assert!(bar_chart(&dir.join("short"), &opts, &cats, &short).is_err());
}

#[test]
fn long_legends_are_cut_with_a_count() {
    let (dir, _guard) = out_dir();
    let series: Vec<Series> = (0..40)
        .map(|i| {
            Series::new(
                format!("run {i}"),
                vec![(0.0, i as f64), (1.0, i as f64 + 1.0)],
            )
        })
        .collect();
    let mut opts = PlotOptions::new("Forty runs", "t", "v");
    opts.height = 400;
    let files = line_chart(&dir.join("legend"), &opts, &series).unwrap();
    let svg = check_files(&files, &opts, &["run 0", "more"]);
    // 400 px leaves room for about 14 lines at this size: the last entries are counted, not drawn.
    assert!(!svg.contains("run 39"));
    let shown = (0..40)
        .filter(|i| svg.contains(&format!("\nrun {i}\n")))
        .count();
    assert!(
        svg.contains(&format!("… {} more", 40 - shown)),
        "{shown} shown"
    );
}

#[test]
fn line_chart_without_finite_points_is_an_error() {
    let (dir, _guard) = out_dir();
    let opts = PlotOptions::new("empty", "x", "y");
    let err = line_chart(
        &dir.join("empty"),
        &opts,
        &[Series::new("nan", vec![(f64::NAN, 1.0)])],
    )
    .unwrap_err();
    assert!(matches!(err, ReportError::PlotInput { .. }), "{err}");
    assert!(!dir.join("empty.svg").exists());
}

#[test]
fn csv_round_trip_is_deterministic() {
    let dir = tempfile::tempdir().unwrap();
    let rows = vec![
        vec![
            Cell::from("paper, k=40"),
            Cell::from(40u32),
            Cell::from(0.1 + 0.2),
            Cell::from(-0.0),
        ],
        vec![
            Cell::from("lru"),
            Cell::from(-3i64),
            Cell::from(f64::NAN),
            Cell::from(1e9),
        ],
    ];
    let (a, b) = (dir.path().join("a.csv"), dir.path().join("b.csv"));
    write_csv(&a, &["policy", "k", "share", "bytes"], &rows).unwrap();
    let mut w = CsvWriter::create(&b, &["policy", "k", "share", "bytes"]).unwrap();
    for r in &rows {
        w.row(r).unwrap();
    }
    assert_eq!(w.rows(), 2);
    assert_eq!(w.finish().unwrap(), b);
    let text = std::fs::read_to_string(&a).unwrap();
    assert_eq!(
        text,
        "policy,k,share,bytes\n\"paper, k=40\",40,0.300000,0.000000\nlru,-3,nan,1000000000.000000\n"
    );
    assert_eq!(std::fs::read(&b).unwrap(), text.as_bytes());

    let t = read_csv(&a).unwrap();
    assert_eq!(t.header, vec!["policy", "k", "share", "bytes"]);
    assert_eq!(t.column("policy").unwrap(), vec!["paper, k=40", "lru"]);
    let share = t.column_f64("share").unwrap();
    assert_eq!(share[0], 0.3);
    assert!(share[1].is_nan());
    assert!(t.column_f64("policy").is_none());

    // A row of the wrong width is an error naming the line, and the file is never published.
    let c = dir.path().join("c.csv");
    let mut w = CsvWriter::create(&c, &["x", "y"]).unwrap();
    w.row(&[Cell::from(1u8), Cell::from(2u8)]).unwrap();
    let err = w.row(&[Cell::from(1u8)]).unwrap_err();
    assert!(matches!(err, ReportError::Csv { line: 3, .. }), "{err}");
    drop(w);
    assert!(!c.exists());
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        2,
        "temp file left behind"
    );
}
