//! A self-contained HTML report: one file, figures inline (SVG markup or PNG as a `data:` URI), a
//! small embedded style sheet for screen and print, no JavaScript, no external resource.
//!
//! Every piece of text given to the builder is HTML-escaped, so data-derived strings (file names,
//! labels) can never inject markup. Void elements are written self-closed (`<meta ... />`), so the
//! document after its DOCTYPE is also well-formed XML (the tests check it as such).
//!
//! ```
//! use report::html::{Report, Section, Table};
//!
//! let table = Table::new(["Parameter", "Ours", "Paper (estimated)"])
//!     .caption("Hammerstein parameters")
//!     .paper_column(2)
//!     .row(["b_r (counts)", "1.4120", "1.4120"]);
//! let html = Report::new("IPA identification")
//!     .section(Section::new("Estimates").paragraph("Values of the paper beside ours.").table(table))
//!     .to_html();
//! assert!(html.contains("<h2 id=\"sec-1\">Estimates</h2>"));
//! ```

use std::path::Path;

use base64::Engine;

use crate::plot::{render_png, render_svg, Figure};
use crate::ReportError;

/// Escapes text for HTML element content and quoted attribute values (`& < > " '`).
pub fn escape(text: &str) -> String {
    let mut out = String::with_capacity(text.len() + text.len() / 8);
    for c in text.chars() {
        match c {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}

/// The tone of a [`Section::callout`]: whether a result meets its acceptance criterion.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// The criterion is met (green rule, "PASS").
    Pass,
    /// The criterion is not met (red rule, "FAIL").
    Fail,
    /// Neutral information (grey rule, "NOTE").
    Note,
}

impl Verdict {
    fn class(self) -> &'static str {
        match self {
            Verdict::Pass => "pass",
            Verdict::Fail => "fail",
            Verdict::Note => "note",
        }
    }

    fn word(self) -> &'static str {
        match self {
            Verdict::Pass => "PASS",
            Verdict::Fail => "FAIL",
            Verdict::Note => "NOTE",
        }
    }
}

/// A table: a header row, body rows and an optional caption. Columns marked with
/// [`Table::paper_column`] hold the paper's published values and are styled apart (tinted, italic)
/// from the values this program computed.
///
/// Rows shorter than the header are padded with empty cells; if a row is longer, the header is
/// padded instead, so every row of the rendered table has the same number of cells.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Table {
    caption: Option<String>,
    header: Vec<String>,
    rows: Vec<Vec<String>>,
    paper_columns: Vec<usize>,
}

impl Table {
    /// A table with the given column headings and no rows.
    pub fn new<I, S>(header: I) -> Self
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        Table {
            header: header.into_iter().map(Into::into).collect(),
            ..Table::default()
        }
    }

    /// Sets the caption (shown above the table, after its number).
    pub fn caption(mut self, caption: impl Into<String>) -> Self {
        self.caption = Some(caption.into());
        self
    }

    /// Appends a body row.
    pub fn row<I, S>(mut self, cells: I) -> Self
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        self.push_row(cells);
        self
    }

    /// Appends a body row (for tables filled in a loop).
    pub fn push_row<I, S>(&mut self, cells: I)
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        self.rows.push(cells.into_iter().map(Into::into).collect());
    }

    /// Marks column `index` (0-based) as holding the paper's values.
    pub fn paper_column(mut self, index: usize) -> Self {
        if !self.paper_columns.contains(&index) {
            self.paper_columns.push(index);
        }
        self
    }

    /// Number of columns of the rendered table (the longest of header and rows).
    pub fn columns(&self) -> usize {
        self.rows
            .iter()
            .map(Vec::len)
            .chain(std::iter::once(self.header.len()))
            .max()
            .unwrap_or(0)
    }

    fn render(&self, number: usize, out: &mut String) {
        let columns = self.columns();
        let class = |c: usize, text: &str| {
            let mut classes = Vec::new();
            if self.paper_columns.contains(&c) {
                classes.push("paper");
            }
            if looks_numeric(text) {
                classes.push("num");
            }
            if classes.is_empty() {
                String::new()
            } else {
                format!(" class=\"{}\"", classes.join(" "))
            }
        };
        // The wrapper scrolls sideways on a narrow screen, so that a wide table never widens the page.
        out.push_str("<div class=\"table-wrap\">\n<table>\n");
        out.push_str(&format!(
            "<caption><span class=\"label\">Table {number}.</span>"
        ));
        if let Some(caption) = &self.caption {
            out.push(' ');
            out.push_str(&escape(caption));
        }
        out.push_str("</caption>\n");
        if !self.header.is_empty() {
            out.push_str("<thead><tr>");
            for c in 0..columns {
                let text = self.header.get(c).map(String::as_str).unwrap_or("");
                let cls = if self.paper_columns.contains(&c) {
                    " class=\"paper\""
                } else {
                    ""
                };
                out.push_str(&format!("<th scope=\"col\"{cls}>{}</th>", escape(text)));
            }
            out.push_str("</tr></thead>\n");
        }
        out.push_str("<tbody>\n");
        for row in &self.rows {
            out.push_str("<tr>");
            for c in 0..columns {
                let text = row.get(c).map(String::as_str).unwrap_or("");
                out.push_str(&format!("<td{}>{}</td>", class(c, text), cell_html(text)));
            }
            out.push_str("</tr>\n");
        }
        out.push_str("</tbody>\n</table>\n</div>\n");
    }
}

/// A cell's escaped content; `value ± std` is split so that a narrow screen may wrap it at the `±`
/// but never inside a number.
fn cell_html(text: &str) -> String {
    match text.split_once(" ± ") {
        Some((v, s)) if looks_numeric(text) => format!(
            "<span class=\"nw\">{}</span> ± <span class=\"nw\">{}</span>",
            escape(v),
            escape(s)
        ),
        _ => escape(text),
    }
}

/// True for cells that start like a number (`-1.5`, `+3`, `−2`, `.5`, `92.97 %`): they are
/// right-aligned with tabular digits so that decimal places line up.
fn looks_numeric(text: &str) -> bool {
    let t = text.trim_start();
    let t = t.strip_prefix(['-', '+', '\u{2212}']).unwrap_or(t);
    let t = t.strip_prefix('.').unwrap_or(t);
    t.chars().next().is_some_and(|c| c.is_ascii_digit())
}

/// A figure's image, as embedded in the page.
#[derive(Debug, Clone, PartialEq)]
enum Image {
    /// SVG markup placed inline (text stays selectable and searchable).
    Svg(String),
    /// PNG bytes embedded as a base64 `data:` URI.
    Png(Vec<u8>),
}

#[derive(Debug, Clone, PartialEq)]
enum Block {
    Paragraph(String),
    List(Vec<String>),
    Code(String),
    Callout(Verdict, String),
    Table(Table),
    Figure {
        image: Image,
        caption: String,
        alt: String,
    },
}

/// A section of the report: a heading (`<h2>`, listed in the table of contents) and its content in
/// the order added.
#[derive(Debug, Clone, PartialEq)]
pub struct Section {
    heading: String,
    id: Option<String>,
    blocks: Vec<Block>,
}

impl Section {
    /// An empty section with the given heading.
    pub fn new(heading: impl Into<String>) -> Self {
        Section {
            heading: heading.into(),
            id: None,
            blocks: Vec::new(),
        }
    }

    /// Sets a stable anchor, written as `<section id="...">` (e.g. `paper-model`), so that links and
    /// tests can find the section whatever its number. Characters other than ASCII letters, digits,
    /// `-` and `_` are replaced by `-`.
    pub fn id(mut self, id: impl Into<String>) -> Self {
        let id: String = id
            .into()
            .chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                    c
                } else {
                    '-'
                }
            })
            .collect();
        self.id = (!id.is_empty()).then_some(id);
        self
    }

    /// The section's anchor set with [`Section::id`], if any.
    pub fn anchor(&self) -> Option<&str> {
        self.id.as_deref()
    }

    /// The section's heading.
    pub fn heading(&self) -> &str {
        &self.heading
    }

    /// Appends a paragraph of (escaped) text.
    pub fn paragraph(mut self, text: impl Into<String>) -> Self {
        self.blocks.push(Block::Paragraph(text.into()));
        self
    }

    /// Appends a bulleted list.
    pub fn list<I, S>(mut self, items: I) -> Self
    where
        I: IntoIterator<Item = S>,
        S: Into<String>,
    {
        self.blocks
            .push(Block::List(items.into_iter().map(Into::into).collect()));
        self
    }

    /// Appends preformatted text (a command line, a terminal table).
    pub fn code(mut self, text: impl Into<String>) -> Self {
        self.blocks.push(Block::Code(text.into()));
        self
    }

    /// Appends a highlighted statement of whether a criterion is met, e.g.
    /// `callout(Verdict::Fail, "overshoot 12.3 % exceeds the paper's 10 % acceptance")`.
    pub fn callout(mut self, verdict: Verdict, text: impl Into<String>) -> Self {
        self.blocks.push(Block::Callout(verdict, text.into()));
        self
    }

    /// Appends a table (numbered in document order).
    pub fn table(mut self, table: Table) -> Self {
        self.blocks.push(Block::Table(table));
        self
    }

    /// Appends a figure given as SVG markup, placed inline. An XML declaration or DOCTYPE before the
    /// `<svg` element is dropped (they are not allowed inside HTML); `alt` is the accessible
    /// description.
    pub fn svg_figure(
        mut self,
        svg: impl Into<String>,
        caption: impl Into<String>,
        alt: impl Into<String>,
    ) -> Self {
        self.blocks.push(Block::Figure {
            image: Image::Svg(svg.into()),
            caption: caption.into(),
            alt: alt.into(),
        });
        self
    }

    /// Appends a figure given as PNG bytes, embedded as a `data:image/png;base64` URI.
    pub fn png_figure(
        mut self,
        png: Vec<u8>,
        caption: impl Into<String>,
        alt: impl Into<String>,
    ) -> Self {
        self.blocks.push(Block::Figure {
            image: Image::Png(png),
            caption: caption.into(),
            alt: alt.into(),
        });
        self
    }

    /// Renders `figure` as SVG and appends it inline (the figure's title is the accessible description).
    pub fn figure(self, figure: &Figure, caption: impl Into<String>) -> Result<Self, ReportError> {
        let svg = render_svg(figure)?;
        Ok(self.svg_figure(svg, caption, figure.title.clone()))
    }

    /// Renders `figure` as PNG and appends it as a `data:` URI (smaller than SVG for long records).
    pub fn figure_png(
        self,
        figure: &Figure,
        caption: impl Into<String>,
    ) -> Result<Self, ReportError> {
        let png = render_png(figure)?;
        Ok(self.png_figure(png, caption, figure.title.clone()))
    }
}

/// Strips anything before the `<svg` element (XML declaration, DOCTYPE, comments).
fn inline_svg(svg: &str) -> &str {
    match svg.find("<svg") {
        Some(i) => &svg[i..],
        None => svg,
    }
}

/// The embedded style sheet: readable on screen, sober in print (no backgrounds lost, figures and
/// tables not split across pages).
const CSS: &str = r#"
:root { color-scheme: light; }
body { font-family: "DejaVu Sans", "Helvetica Neue", Arial, sans-serif; line-height: 1.5; color: #111;
       background: #fff; max-width: 62rem; margin: 0 auto; padding: 1.5rem 1.25rem 3rem;
       overflow-wrap: break-word; }
main, section, figure, .callout, nav.toc { max-width: 100%; min-width: 0; }
.table-wrap { max-width: 100%; overflow-x: auto; margin: 1rem 0; }
.table-wrap table { margin: 0; }
h1 { font-size: 1.8rem; margin: 0 0 0.3rem; }
h2 { font-size: 1.35rem; margin: 2.2rem 0 0.6rem; border-bottom: 1px solid #bbb; padding-bottom: 0.2rem; }
p.subtitle { color: #444; margin-top: 0; }
nav.toc { border: 1px solid #ddd; padding: 0.5rem 1rem; margin: 1rem 0; background: #fafafa; }
nav.toc ol { margin: 0.3rem 0; padding-left: 1.4rem; }
a { color: #0b5394; }
table { border-collapse: collapse; margin: 1rem 0; font-size: 0.95rem; }
caption { caption-side: top; text-align: left; font-weight: 600; padding-bottom: 0.35rem; }
th, td { border: 1px solid #999; padding: 0.25rem 0.6rem; text-align: left; vertical-align: top; }
thead th { background: #e8e8e8; }
td.num { text-align: right; font-variant-numeric: tabular-nums; white-space: nowrap; }
.nw { white-space: nowrap; }
th.paper, td.paper { background: #f3f0e6; font-style: italic; color: #333; }
figure { margin: 1.2rem 0; break-inside: avoid; page-break-inside: avoid; }
figure svg, figure img { display: block; max-width: 100%; height: auto; border: 1px solid #ddd; }
figcaption { font-size: 0.95rem; color: #222; margin-top: 0.35rem; }
.label { font-weight: 700; }
pre { background: #f5f5f5; border: 1px solid #ddd; padding: 0.6rem; overflow-x: auto; font-size: 0.9rem; }
.callout { border-left: 0.35rem solid #888; padding: 0.4rem 0.8rem; margin: 1rem 0; background: #f7f7f7; }
.callout.pass { border-color: #009e73; }
.callout.fail { border-color: #d55e00; }
.callout .verdict { font-weight: 700; margin-right: 0.4rem; }
footer { margin-top: 3rem; font-size: 0.85rem; color: #555; border-top: 1px solid #ccc; padding-top: 0.5rem; }
@media (max-width: 60rem) {
  td.num { white-space: normal; }
  th, td { padding: 0.2rem 0.35rem; }
  table { font-size: 0.88rem; }
}
@media print {
  body { max-width: none; padding: 0; font-size: 10.5pt; }
  nav.toc { display: none; }
  a { color: inherit; text-decoration: none; }
  table, figure, .callout { break-inside: avoid; page-break-inside: avoid; }
  .table-wrap { overflow: visible; }
  h2 { break-after: avoid; page-break-after: avoid; }
  figure svg, figure img { max-height: 23cm; width: auto; }
  th.paper, td.paper, thead th, .callout { -webkit-print-color-adjust: exact; print-color-adjust: exact; }
}
"#;

/// The report under construction: a title, an optional subtitle and introduction, sections in
/// order, and an optional footer.
#[derive(Debug, Clone, PartialEq)]
pub struct Report {
    title: String,
    subtitle: Option<String>,
    intro: Vec<String>,
    sections: Vec<Section>,
    footer: Option<String>,
}

impl Report {
    /// An empty report with the given title (`<title>` and `<h1>`).
    pub fn new(title: impl Into<String>) -> Self {
        Report {
            title: title.into(),
            subtitle: None,
            intro: Vec::new(),
            sections: Vec::new(),
            footer: None,
        }
    }

    /// Sets a subtitle shown under the title (e.g. the plant, the seed and the date).
    pub fn subtitle(mut self, text: impl Into<String>) -> Self {
        self.subtitle = Some(text.into());
        self
    }

    /// Appends an introductory paragraph, shown before the table of contents.
    pub fn intro(mut self, text: impl Into<String>) -> Self {
        self.intro.push(text.into());
        self
    }

    /// Appends a section (builder style).
    pub fn section(mut self, section: Section) -> Self {
        self.sections.push(section);
        self
    }

    /// Appends a section (for reports assembled step by step).
    pub fn push_section(&mut self, section: Section) {
        self.sections.push(section);
    }

    /// Sets the footer line (e.g. the program version and the command that produced the report).
    pub fn footer(mut self, text: impl Into<String>) -> Self {
        self.footer = Some(text.into());
        self
    }

    /// The sections added so far.
    pub fn sections(&self) -> &[Section] {
        &self.sections
    }

    /// The complete HTML document.
    pub fn to_html(&self) -> String {
        let mut out = String::with_capacity(64 * 1024);
        out.push_str("<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\" />\n");
        out.push_str(
            "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\" />\n",
        );
        out.push_str(&format!(
            "<meta name=\"generator\" content=\"ipa-sysid {}\" />\n",
            env!("CARGO_PKG_VERSION")
        ));
        out.push_str(&format!(
            "<title>{}</title>\n<style>{CSS}</style>\n</head>\n<body>\n",
            escape(&self.title)
        ));
        out.push_str(&format!("<header>\n<h1>{}</h1>\n", escape(&self.title)));
        if let Some(subtitle) = &self.subtitle {
            out.push_str(&format!("<p class=\"subtitle\">{}</p>\n", escape(subtitle)));
        }
        out.push_str("</header>\n");
        for paragraph in &self.intro {
            out.push_str(&format!("<p>{}</p>\n", escape(paragraph)));
        }
        if self.sections.len() > 1 {
            out.push_str("<nav class=\"toc\"><strong>Contents</strong>\n<ol>\n");
            for (i, section) in self.sections.iter().enumerate() {
                out.push_str(&format!(
                    "<li><a href=\"#sec-{}\">{}</a></li>\n",
                    i + 1,
                    escape(&section.heading)
                ));
            }
            out.push_str("</ol>\n</nav>\n");
        }
        out.push_str("<main>\n");
        let (mut tables, mut figures) = (0usize, 0usize);
        for (i, section) in self.sections.iter().enumerate() {
            let anchor = section
                .id
                .as_ref()
                .map(|id| format!(" id=\"{}\"", escape(id)))
                .unwrap_or_default();
            out.push_str(&format!(
                "<section{anchor}>\n<h2 id=\"sec-{}\">{}</h2>\n",
                i + 1,
                escape(&section.heading)
            ));
            for block in &section.blocks {
                match block {
                    Block::Paragraph(text) => out.push_str(&format!("<p>{}</p>\n", escape(text))),
                    Block::List(items) => {
                        out.push_str("<ul>\n");
                        for item in items {
                            out.push_str(&format!("<li>{}</li>\n", escape(item)));
                        }
                        out.push_str("</ul>\n");
                    }
                    Block::Code(text) => out.push_str(&format!("<pre>{}</pre>\n", escape(text))),
                    Block::Callout(verdict, text) => out.push_str(&format!(
                        "<div class=\"callout {}\"><span class=\"verdict\">{}</span>{}</div>\n",
                        verdict.class(),
                        verdict.word(),
                        escape(text)
                    )),
                    Block::Table(table) => {
                        tables += 1;
                        table.render(tables, &mut out);
                    }
                    Block::Figure {
                        image,
                        caption,
                        alt,
                    } => {
                        figures += 1;
                        out.push_str("<figure>\n");
                        match image {
                            Image::Svg(svg) => {
                                out.push_str(&format!(
                                    "<div role=\"img\" aria-label=\"{}\">\n",
                                    escape(alt)
                                ));
                                out.push_str(inline_svg(svg));
                                out.push_str("\n</div>\n");
                            }
                            Image::Png(png) => {
                                let data = base64::engine::general_purpose::STANDARD.encode(png);
                                out.push_str(&format!(
                                    "<img src=\"data:image/png;base64,{data}\" alt=\"{}\" />\n",
                                    escape(alt)
                                ));
                            }
                        }
                        out.push_str(&format!(
                            "<figcaption><span class=\"label\">Figure {figures}.</span> {}</figcaption>\n",
                            escape(caption)
                        ));
                        out.push_str("</figure>\n");
                    }
                }
            }
            out.push_str("</section>\n");
        }
        out.push_str("</main>\n");
        if let Some(footer) = &self.footer {
            out.push_str(&format!("<footer>{}</footer>\n", escape(footer)));
        }
        out.push_str("</body>\n</html>\n");
        out
    }

    /// Writes the document to `path` atomically.
    pub fn save(&self, path: &Path) -> Result<(), ReportError> {
        sysid_io::write_atomic(path, self.to_html().as_bytes())?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    // Numbers in any sign convention are right-aligned; words and empty cells are not.
    #[test]
    fn numeric_cells_are_recognised_by_their_first_characters() {
        for t in [
            "1.41",
            "-1.5",
            "+3",
            "\u{2212}2",
            ".5",
            "92.97 %",
            "7.498e-4",
        ] {
            assert!(looks_numeric(t), "{t}");
        }
        for t in ["", "b_r", "n/a", "-", "stable"] {
            assert!(!looks_numeric(t), "{t}");
        }
    }

    // The inline SVG starts at its root element; the XML prolog is not valid inside HTML.
    #[test]
    fn inline_svg_drops_the_xml_prolog() {
        assert_eq!(
            inline_svg("<?xml version=\"1.0\"?>\n<svg a=\"1\"/>"),
            "<svg a=\"1\"/>"
        );
    }
}
