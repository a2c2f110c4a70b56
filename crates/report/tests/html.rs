//! HTML report: escaping, document structure, tables, inline figures, atomic save.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)] // tests, benches and examples may panic

mod common;

use base64::Engine;
use common::{check_well_formed, png_size};
use report::html::{escape, Report, Section, Table, Verdict};
use report::plot::{render_png, Figure, Panel, Series};

/// Cells of each `<tr>` of the n-th table (0-based) as (tag, text) pairs, parsed independently of
/// the builder by scanning for `<th`/`<td` in the table's markup.
fn table_rows(html: &str, n: usize) -> Vec<Vec<(String, String)>> {
    let start = html.match_indices("<table>").nth(n).expect("table").0;
    let end = start + html[start..].find("</table>").expect("end of table");
    let table = &html[start..end];
    table
        .split("<tr>")
        .skip(1)
        .map(|row| {
            let row = &row[..row.find("</tr>").expect("end of row")];
            let mut cells = Vec::new();
            let mut rest = row;
            while let Some(p) = rest.find("<t") {
                let tag = rest[p + 1..p + 3].to_string();
                let open_end = p + rest[p..].find('>').unwrap() + 1;
                let close = format!("</{tag}>");
                let text_end = open_end + rest[open_end..].find(&close).unwrap();
                cells.push((
                    rest[p..open_end].to_string(),
                    rest[open_end..text_end].to_string(),
                ));
                rest = &rest[text_end + close.len()..];
            }
            cells
        })
        .collect()
}

// The five characters with a meaning in HTML are replaced by their entities; others pass through.
#[test]
fn escape_replaces_the_five_markup_characters() {
    assert_eq!(
        escape(r#"<a href="x">Tom & 'Jerry'</a>"#),
        "&lt;a href=&quot;x&quot;&gt;Tom &amp; &#39;Jerry&#39;&lt;/a&gt;"
    );
    assert_eq!(escape("θ = [m_r, b_r] ± 5 %"), "θ = [m_r, b_r] ± 5 %");
    assert_eq!(escape(""), "");
}

// Text from data cannot inject markup anywhere: title, subtitle, headings, paragraphs, lists, code,
// callouts, captions, table cells, figure captions and alt texts are all escaped.
#[test]
fn every_text_field_is_escaped() {
    let evil = "<script>alert('x')</script>&";
    let html = Report::new(evil)
        .subtitle(evil)
        .intro(evil)
        .footer(evil)
        .section(
            Section::new(evil)
                .paragraph(evil)
                .list([evil])
                .code(evil)
                .callout(Verdict::Fail, evil)
                .table(Table::new([evil]).caption(evil).row([evil]))
                .png_figure(vec![1, 2, 3], evil, evil),
        )
        .section(Section::new("second"))
        .to_html();
    assert!(!html.contains("<script"), "raw <script> in output");
    let escaped = "&lt;script&gt;alert(&#39;x&#39;)&lt;/script&gt;&amp;";
    // title, h1, subtitle, intro, toc entry, h2, paragraph, list item, code, callout, caption, th, td,
    // alt, figcaption, footer
    assert_eq!(html.matches(escaped).count(), 16);
    check_well_formed(&html).unwrap_or_else(|e| panic!("{e}"));
}

// A document is one <html> with one <head> and one <body>, a <title>, a <style> and no script or
// external reference; sections get numbered ids that the table of contents links to.
#[test]
fn document_structure() {
    let html = Report::new("T")
        .section(Section::new("A").paragraph("a"))
        .section(Section::new("B").paragraph("b"))
        .section(Section::new("C"))
        .to_html();
    assert!(html.starts_with("<!DOCTYPE html>\n"));
    let names = check_well_formed(&html).unwrap_or_else(|e| panic!("{e}"));
    let count = |n: &str| names.iter().filter(|x| *x == n).count();
    assert_eq!(
        (
            count("html"),
            count("head"),
            count("body"),
            count("title"),
            count("style")
        ),
        (1, 1, 1, 1, 1)
    );
    assert_eq!(
        (count("h1"), count("h2"), count("section"), count("script")),
        (1, 3, 3, 0)
    );
    for (i, h) in ["A", "B", "C"].iter().enumerate() {
        assert!(html.contains(&format!("<h2 id=\"sec-{}\">{h}</h2>", i + 1)));
        assert!(html.contains(&format!("<a href=\"#sec-{}\">{h}</a>", i + 1)));
    }
    assert!(!html.contains("src=\"http") && !html.contains("href=\"http"));
    // A single section needs no table of contents.
    assert!(!Report::new("T")
        .section(Section::new("only"))
        .to_html()
        .contains("<nav"));
}

// Every row has as many cells as the widest of header and rows; short rows are padded with empty
// cells; paper columns carry class "paper" in the header and in every row; tables are numbered.
#[test]
fn tables_have_rectangular_rows_and_marked_paper_columns() {
    let t1 = Table::new(["Criterion", "ARX", "Hammerstein", "Paper"])
        .caption("Validation")
        .paper_column(3)
        .row(["Best fit (%)", "87.31", "92.97", "92.9665"])
        .row(["Loss"]);
    let t2 = Table::new(["a"]).row(["1", "2", "3"]);
    let html = Report::new("T")
        .section(Section::new("S").table(t1).table(t2))
        .to_html();
    let rows = table_rows(&html, 0);
    assert_eq!(rows.len(), 3);
    assert!(rows.iter().all(|r| r.len() == 4), "{rows:?}");
    assert!(rows[0].iter().all(|(tag, _)| tag.starts_with("<th")));
    assert_eq!(
        rows[2].iter().map(|(_, t)| t.as_str()).collect::<Vec<_>>(),
        ["Loss", "", "", ""]
    );
    for row in &rows {
        for (c, (tag, _)) in row.iter().enumerate() {
            assert_eq!(tag.contains("paper"), c == 3, "column {c}: {tag}");
        }
    }
    // Numbers are right-aligned, words are not.
    assert!(rows[1][1].0.contains("num") && !rows[1][0].0.contains("num"));
    let rows = table_rows(&html, 1);
    assert!(
        rows.iter().all(|r| r.len() == 3),
        "header padded to the longest row"
    );
    assert!(html.contains("<caption><span class=\"label\">Table 1.</span> Validation</caption>"));
    assert!(html.contains("<caption><span class=\"label\">Table 2.</span></caption>"));
}

// A PNG figure is an <img> whose data: URI decodes back to the very same bytes; an SVG figure is
// inline with its XML prolog removed; figures are numbered in order.
#[test]
fn figures_are_embedded_inline() {
    let fig = Figure::new("Fig").size(300, 200).panel(
        Panel::new("t (s)", "y (mm)").series(Series::line("y", vec![0.0, 1.0], vec![0.0, 1.0])),
    );
    let png = render_png(&fig).unwrap();
    let html = Report::new("T")
        .section(
            Section::new("S")
                .png_figure(png.clone(), "first", "alt one")
                .svg_figure("<?xml version=\"1.0\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"10\" height=\"10\"></svg>", "second", "alt two")
                .figure(&fig, "third")
                .unwrap()
                .figure_png(&fig, "fourth")
                .unwrap(),
        )
        .to_html();
    let prefix = "<img src=\"data:image/png;base64,";
    let at = html.find(prefix).unwrap() + prefix.len();
    let b64 = &html[at..at + html[at..].find('"').unwrap()];
    assert_eq!(
        base64::engine::general_purpose::STANDARD
            .decode(b64)
            .unwrap(),
        png
    );
    assert_eq!(png_size(&png).unwrap(), (300, 200));
    assert!(!html.contains("<?xml"));
    for (i, c) in ["first", "second", "third", "fourth"].iter().enumerate() {
        assert!(html.contains(&format!(
            "<span class=\"label\">Figure {}.</span> {c}</figcaption>",
            i + 1
        )));
    }
    let names = check_well_formed(&html).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(names.iter().filter(|n| *n == "svg").count(), 2);
    assert_eq!(names.iter().filter(|n| *n == "img").count(), 2);
}

// save() writes exactly to_html() and leaves no temporary file; a missing folder is an error that
// names the path.
#[test]
fn save_writes_the_document_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let report = Report::new("T").section(Section::new("S").paragraph("p"));
    let path = dir.path().join("report.html");
    report.save(&path).unwrap();
    assert_eq!(std::fs::read_to_string(&path).unwrap(), report.to_html());
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    let bad = dir.path().join("missing").join("report.html");
    let e = report.save(&bad).unwrap_err();
    assert!(e.to_string().contains("missing"), "{e}");
    assert!(!e.is_numerical());
}

// A section anchor is written on <section>, sanitised; the h2 keeps its numbered id for the contents.
#[test]
fn section_ids_are_written_and_sanitised() {
    let html = Report::new("t")
        .section(Section::new("Residual analysis").id("residuals"))
        .section(Section::new("Odd").id("a b\"<c>"))
        .section(Section::new("None"))
        .to_html();
    assert!(html.contains("<section id=\"residuals\">\n<h2 id=\"sec-1\">Residual analysis</h2>"));
    assert!(html.contains("<section id=\"a-b--c-\">\n<h2 id=\"sec-2\">Odd</h2>"));
    assert!(html.contains("<section>\n<h2 id=\"sec-3\">None</h2>"));
    assert_eq!(
        Section::new("x").id("paper-model").anchor(),
        Some("paper-model")
    );
}

// Wide tables scroll inside their own box; "value ± std" may wrap at the ± but not inside a number.
#[test]
fn tables_scroll_in_a_wrapper_and_deviations_wrap_only_at_the_sign() {
    let html = Report::new("t")
        .section(
            Section::new("s").table(
                Table::new(["p", "v"])
                    .row(["b_r", "30.83 ± 3.5"])
                    .row(["x", "a ± b"]),
            ),
        )
        .to_html();
    assert!(html.contains("<div class=\"table-wrap\">\n<table>"));
    assert!(html.contains("</table>\n</div>"));
    assert!(html.contains(
        "<td class=\"num\"><span class=\"nw\">30.83</span> ± <span class=\"nw\">3.5</span></td>"
    ));
    // Not a number: left as plain escaped text.
    assert!(html.contains("<td>a ± b</td>"));
    assert!(html.contains(".table-wrap { max-width: 100%; overflow-x: auto;"));
    assert!(html.contains("@media print"));
}
