//! `repertoire report DIR`: every chart a run folder supports, with its tables, gathered into
//! one page, `DIR/report/index.md` and a self-contained `DIR/report/index.html` (the SVG charts
//! inline, so the file can be mailed or opened offline).
//!
//! What it looks for in DIR: `metrics.csv` (a training run: learning curves with every reward
//! term), `curriculum.csv` (a meta-controller run: the zone schedule), `report.json` or
//! `eval/report.json` (an evaluation: the zone table, the success map, transition matrices; or a
//! warehouse's phase table and pick-up maps, or a toss's strike zone),
//! and `table.md` (an ablation's table).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use anyhow::{Context, Result, bail};
use repertoire_meta::eval::MetaReport;
use repertoire_meta::tasks::task_eval::{TossReport, WarehouseReport};
use repertoire_report::{CurriculumPoint, curriculum_schedule, learning_curves, read_table, write_atomic};

/// One section of the page: a heading, Markdown text (tables included) and charts.
struct Section {
    title: String,
    text: String,
    charts: Vec<[PathBuf; 2]>,
}

/// Writes DIR/report/ and returns the page's path.
pub fn run(dir: &Path) -> Result<PathBuf> {
    if !dir.is_dir() {
        bail!("{}: not a folder (give a run, evaluation or ablation folder)", dir.display());
    }
    let out = dir.join("report");
    std::fs::create_dir_all(&out).with_context(|| format!("{}: cannot create", out.display()))?;
    let sections: Vec<Section> = [
        training_section(dir, &out)?,
        curriculum_section(dir, &out)?,
        evaluation_section(dir, &out)?,
        replays_section(dir)?,
        ablation_section(dir, &out)?,
    ]
    .into_iter()
    .flatten()
    .collect();

    if sections.is_empty() {
        bail!(
            "{}: nothing to report (looked for metrics.csv, curriculum.csv, report.json, eval/report.json, table.md)",
            dir.display()
        );
    }
    let title = format!("Report: {}", dir.display());
    let md = markdown(&title, &sections, &out);
    let html = html(&title, &sections)?;
    write_atomic(&out.join("index.md"), md.as_bytes())?;
    write_atomic(&out.join("index.html"), html.as_bytes())?;
    Ok(out.join("index.html"))
}

/// Training: the run's learning curves and last figures (metrics.csv).
fn training_section(dir: &Path, out: &Path) -> Result<Option<Section>> {
    let metrics = dir.join("metrics.csv");
    if metrics.exists() {
        let files = learning_curves(&metrics, &out.join("curves"))?;
        let t = read_table(&metrics)?;
        let last = |c: &str| t.column(c).ok().and_then(|v| v.iter().rev().copied().find(|x| x.is_finite()));
        let mut text = String::from(
            "| iterations | environment steps | last mean return | last early-termination rate |\n|---:|---:|---:|---:|\n",
        );
        let _ = writeln!(
            text,
            "| {} | {} | {:.2} | {:.1}% |",
            t.rows.len(),
            last("global_step").unwrap_or(0.0),
            last("mean_return").unwrap_or(f64::NAN),
            100.0 * last("termination_rate").unwrap_or(f64::NAN)
        );
        return Ok(Some(Section { title: "Training".into(), text, charts: pairs(files) }));
    }
    Ok(None)
}

/// The zone curriculum's schedule (curriculum.csv).
fn curriculum_section(dir: &Path, out: &Path) -> Result<Option<Section>> {
    let schedule = dir.join("curriculum.csv");
    if schedule.exists() {
        let t = read_table(&schedule)?;
        let (its, names, index, rate) =
            (t.column("iteration")?, t.text_column("zone")?, t.column("zone_index")?, t.column("success_window")?);
        let threshold = t.column("advance_at")?.first().copied().unwrap_or(f64::NAN);
        let mut zones: Vec<(usize, String)> = Vec::new();
        for (n, &i) in names.iter().zip(&index) {
            if !zones.iter().any(|(k, _)| *k == i as usize) {
                zones.push((i as usize, n.clone()));
            }
        }
        zones.sort();
        let count = zones.last().map_or(0, |z| z.0 + 1);
        let labels: Vec<String> = (0..count)
            .map(|k| zones.iter().find(|z| z.0 == k).map_or_else(|| format!("zone {k}"), |z| z.1.clone()))
            .collect();
        let points: Vec<CurriculumPoint> = its
            .iter()
            .zip(&index)
            .zip(&rate)
            .map(|((&iteration, &zone), &success)| CurriculumPoint { iteration, zone: zone as usize, success })
            .collect();
        let chart = curriculum_schedule(&out.join("curriculum"), &labels, threshold, &points)?;
        let mut text = String::new();
        let mut previous = None;
        for ((it, name), &i) in its.iter().zip(&names).zip(&index) {
            if previous.is_some_and(|p| p != i) {
                let _ = writeln!(text, "- iteration {it}: advanced to `{name}`");
            }
            previous = Some(i);
        }
        if text.is_empty() {
            let _ = writeln!(
                text,
                "The curriculum stayed in `{}` for all {} iterations (advances at {:.0}% windowed success).",
                names.first().map_or("?", String::as_str),
                its.len(),
                100.0 * threshold
            );
        }
        return Ok(Some(Section { title: "Zone curriculum".into(), text, charts: vec![chart] }));
    }
    Ok(None)
}

/// An evaluation's tables and pictures (report.json of sitting, the warehouse or the toss).
fn evaluation_section(dir: &Path, out: &Path) -> Result<Option<Section>> {
    let report = [dir.join("report.json"), dir.join("eval").join("report.json")].into_iter().find(|p| p.exists());
    if let Some(path) = report {
        let text = std::fs::read_to_string(&path).with_context(|| format!("{}: cannot read", path.display()))?;
        let pair = |stem: &Path| [stem.with_extension("png"), stem.with_extension("svg")];
        match serde_json::from_str::<MetaReport>(&text) {
            Ok(r) => {
                r.plot(out)?;
                let mut charts = vec![[out.join("heatmap.png"), out.join("heatmap.svg")]];
                for (side, _) in &r.transitions {
                    charts.push(pair(&out.join(format!("transitions-{side}"))));
                }
                return Ok(Some(Section { title: "Evaluation".into(), text: r.markdown(), charts }));
            }
            Err(sit) => {
                // A warehouse or toss evaluation; otherwise the sitting report's complaint.
                if let Ok(r) = serde_json::from_str::<WarehouseReport>(&text) {
                    let charts = r.plot(out)?.iter().map(|s| pair(s)).collect();
                    return Ok(Some(Section { title: "Warehouse evaluation".into(), text: r.markdown(), charts }));
                } else if let Ok(r) = serde_json::from_str::<TossReport>(&text) {
                    let charts = vec![pair(&r.plot(out)?)];
                    return Ok(Some(Section { title: "Toss evaluation".into(), text: r.markdown(), charts }));
                } else {
                    return Err(
                        anyhow::Error::new(sit).context(format!("{}: not an evaluation report", path.display()))
                    );
                }
            }
        }
    }
    Ok(None)
}

/// Links to the worst episodes' recordings and replay pages (worst/).
fn replays_section(dir: &Path) -> Result<Option<Section>> {
    let worst = dir.join("worst");
    if worst.is_dir() {
        let mut recs: Vec<PathBuf> = std::fs::read_dir(&worst)
            .with_context(|| format!("{}: cannot list", worst.display()))?
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "rec"))
            .collect();
        recs.sort();
        if !recs.is_empty() {
            let mut text = String::from("The worst trials, recorded as they ran:\n\n");
            for rec in &recs {
                let page = rec.with_extension("html");
                let name = rec.file_name().map_or_else(String::new, |n| n.to_string_lossy().into_owned());
                if page.exists() {
                    let _ = writeln!(
                        text,
                        "- [{name}](../worst/{}) (replay page)",
                        page.file_name().unwrap_or_default().to_string_lossy()
                    );
                } else {
                    let _ = writeln!(text, "- `{name}`");
                }
            }
            let _ = writeln!(text, "\nMake or refresh the pages with `repertoire replay {}`.", dir.display());
            return Ok(Some(Section { title: "Replays".into(), text, charts: Vec::new() }));
        }
    }
    Ok(None)
}

/// An ablation's table and chart (table.md).
fn ablation_section(dir: &Path, out: &Path) -> Result<Option<Section>> {
    let table = dir.join("table.md");
    if table.exists() {
        let text = std::fs::read_to_string(&table).with_context(|| format!("{}: cannot read", table.display()))?;
        // `ablate` draws its chart beside the table; the page takes a copy into its folder.
        let mut charts = Vec::new();
        if dir.join("ablation.png").exists() && dir.join("ablation.svg").exists() {
            let pair = ["png", "svg"].map(|ext| out.join(format!("ablation.{ext}")));
            for (ext, to) in ["png", "svg"].iter().zip(&pair) {
                let bytes = std::fs::read(dir.join(format!("ablation.{ext}")))
                    .with_context(|| format!("{}: cannot read", dir.join(format!("ablation.{ext}")).display()))?;
                write_atomic(to, &bytes)?;
            }
            charts.push(pair);
        }
        return Ok(Some(Section { title: "Ablation".into(), text, charts }));
    }
    Ok(None)
}

/// Chart files as (png, svg) pairs.
fn pairs(files: Vec<PathBuf>) -> Vec<[PathBuf; 2]> {
    files.chunks(2).filter(|c| c.len() == 2).map(|c| [c[0].clone(), c[1].clone()]).collect()
}

fn markdown(title: &str, sections: &[Section], out: &Path) -> String {
    let mut md = format!("# {title}\n");
    for s in sections {
        let _ = write!(md, "\n## {}\n\n{}\n", s.title, s.text.trim_end());
        for [png, _] in &s.charts {
            let rel = png.strip_prefix(out).unwrap_or(png);
            let _ = write!(md, "\n![{}]({})\n", rel.display(), rel.display());
        }
    }
    md
}

/// `[text](href)` as an HTML link.
fn links(s: &str) -> String {
    let mut out = String::new();
    let mut rest = s;
    while let Some(open) = rest.find('[') {
        let Some(mid) = rest[open..].find("](").map(|m| open + m) else { break };
        let Some(close) = rest[mid..].find(')').map(|c| mid + c) else { break };
        out.push_str(&rest[..open]);
        let _ = write!(out, "<a href=\"{}\">{}</a>", &rest[mid + 2..close], &rest[open + 1..mid]);
        rest = &rest[close + 1..];
    }
    out.push_str(rest);
    out
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

/// Markdown as the reports write it (tables, list items, paragraphs, `#` headings, `code`) to
/// HTML.
fn text_html(md: &str) -> String {
    let mut html = String::new();
    let mut in_table = false;
    let mut in_list = false;
    let inline = |s: &str| {
        let e = links(&escape(s));
        let mut out = String::new();
        for (i, part) in e.split('`').enumerate() {
            if i % 2 == 1 {
                let _ = write!(out, "<code>{part}</code>");
            } else {
                out.push_str(part);
            }
        }
        out
    };
    for line in md.lines() {
        let t = line.trim();
        if t.starts_with('|') {
            if !in_table {
                html.push_str("<table>\n");
                in_table = true;
            }
            if t.trim_matches(|c| c == '|' || c == '-' || c == ':' || c == ' ').is_empty() {
                continue;
            }
            let cells: Vec<&str> = t.trim_matches('|').split('|').collect();
            html.push_str("<tr>");
            for c in cells {
                let _ = write!(html, "<td>{}</td>", inline(c.trim()));
            }
            html.push_str("</tr>\n");
            continue;
        }
        if in_table {
            html.push_str("</table>\n");
            in_table = false;
        }
        if let Some(item) = t.strip_prefix("- ") {
            if !in_list {
                html.push_str("<ul>\n");
                in_list = true;
            }
            let _ = writeln!(html, "<li>{}</li>", inline(item));
            continue;
        }
        if in_list {
            html.push_str("</ul>\n");
            in_list = false;
        }
        if t.is_empty() {
            continue;
        }
        if let Some(h) = t.strip_prefix('#') {
            let _ = writeln!(html, "<h3>{}</h3>", inline(h.trim_start_matches('#').trim()));
        } else {
            let _ = writeln!(html, "<p>{}</p>", inline(t));
        }
    }
    if in_table {
        html.push_str("</table>\n");
    }
    if in_list {
        html.push_str("</ul>\n");
    }
    html
}

fn html(title: &str, sections: &[Section]) -> Result<String> {
    let mut html = format!(
        "<!doctype html>\n<html><head><meta charset=\"utf-8\"><title>{t}</title><style>\
         body{{font-family:sans-serif;max-width:1000px;margin:2em auto;color:#222}}\
         table{{border-collapse:collapse;margin:1em 0}}td{{border:1px solid #ccc;padding:3px 8px;text-align:right}}\
         tr:first-child td{{font-weight:bold;background:#f3f3f3}}figure{{margin:1em 0}}svg{{max-width:100%;height:auto}}\
         </style></head><body>\n<h1>{t}</h1>\n",
        t = escape(title)
    );
    for s in sections {
        let _ = write!(html, "<h2>{}</h2>\n{}", escape(&s.title), text_html(&s.text));
        for [_, svg] in &s.charts {
            let text = std::fs::read_to_string(svg).with_context(|| format!("{}: cannot read", svg.display()))?;
            let body = text.find("<svg").map_or(text.as_str(), |i| &text[i..]);
            let _ = writeln!(html, "<figure>{body}</figure>");
        }
    }
    html.push_str("</body></html>\n");
    Ok(html)
}
