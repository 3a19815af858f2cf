//! A self-contained HTML page built piece by piece: headings, paragraphs, tables, and
//! figures inlined (SVG as markup, PNG as base64), so `report.html` travels as one file.

use std::path::Path;

use camplace_config::write_atomic;

use super::base64;
use crate::{Error, Result};

/// The page under construction.
#[derive(Debug, Clone, Default)]
pub struct HtmlPage {
    title: String,
    body: String,
}

/// `text` with &, < and > escaped.
pub fn escape(text: &str) -> String {
    text.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

impl HtmlPage {
    /// An empty page.
    pub fn new(title: &str) -> HtmlPage {
        HtmlPage { title: title.to_string(), body: String::new() }
    }

    /// A heading of level 1–3, with an id made of its words (so `report.html#mounting-tolerances`
    /// opens there).
    pub fn heading(&mut self, level: u8, text: &str) {
        let l = level.clamp(1, 3);
        let id: String = text
            .to_lowercase()
            .split(|c: char| !c.is_ascii_alphanumeric())
            .filter(|w| !w.is_empty())
            .collect::<Vec<_>>()
            .join("-");
        self.body.push_str(&format!("<h{l} id=\"{id}\">{}</h{l}>\n", escape(text)));
    }

    /// A paragraph of plain text.
    pub fn paragraph(&mut self, text: &str) {
        self.body.push_str(&format!("<p>{}</p>\n", escape(text)));
    }

    /// A bulleted list of plain-text items.
    pub fn list(&mut self, items: &[String]) {
        self.body.push_str("<ul>\n");
        for i in items {
            self.body.push_str(&format!("<li>{}</li>\n", escape(i)));
        }
        self.body.push_str("</ul>\n");
    }

    /// A table with a header row.
    pub fn table(&mut self, header: &[&str], rows: &[Vec<String>]) {
        self.body.push_str("<table>\n<tr>");
        for h in header {
            self.body.push_str(&format!("<th>{}</th>", escape(h)));
        }
        self.body.push_str("</tr>\n");
        for r in rows {
            self.body.push_str("<tr>");
            for c in r {
                self.body.push_str(&format!("<td>{}</td>", escape(c)));
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</table>\n");
    }

    /// A two-column table of labelled values, each row marked `data-key="KEY"` so that a
    /// reader (or a test in a browser) can find a value by its key: rows of (key, label, value).
    pub fn keyed_table(&mut self, id: &str, rows: &[(String, String, String)]) {
        self.body.push_str(&format!("<table id=\"{}\">\n", escape(id)));
        for (key, label, value) in rows {
            self.body.push_str(&format!(
                "<tr data-key=\"{}\"><th>{}</th><td>{}</td></tr>\n",
                escape(key).replace('"', "&quot;"),
                escape(label),
                escape(value)
            ));
        }
        self.body.push_str("</table>\n");
    }

    /// Markup written as it is (the page's own layout only, never outside text).
    pub fn raw(&mut self, html: &str) {
        self.body.push_str(html);
    }

    /// Preformatted text (settings).
    pub fn pre(&mut self, text: &str) {
        self.body.push_str(&format!("<pre>{}</pre>\n", escape(text)));
    }

    /// An SVG file inlined as markup.
    pub fn svg(&mut self, path: &Path) -> Result<()> {
        let text =
            std::fs::read_to_string(path).map_err(|e| Error::Other(format!("{}: cannot read: {e}", path.display())))?;
        let start = text.find("<svg").unwrap_or(0);
        self.body.push_str(&format!("<div class=\"fig\">{}</div>\n", &text[start..]));
        Ok(())
    }

    /// A PNG file inlined as base64 with a caption.
    pub fn png(&mut self, path: &Path, caption: &str) -> Result<()> {
        let bytes = std::fs::read(path).map_err(|e| Error::Other(format!("{}: cannot read: {e}", path.display())))?;
        self.body.push_str(&format!(
            "<figure><img alt=\"{0}\" src=\"data:image/png;base64,{1}\"><figcaption>{0}</figcaption></figure>\n",
            escape(caption),
            base64::encode(&bytes)
        ));
        Ok(())
    }

    /// Writes the page to `path` atomically.
    pub fn write(&self, path: &Path) -> Result<()> {
        Ok(write_atomic(path, self.html().as_bytes())?)
    }

    /// The whole page's text.
    pub fn html(&self) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{0}</title>\n<style>\
body{{font-family:sans-serif;max-width:1200px;margin:2em auto;padding:0 1em;color:#222}}\
table{{border-collapse:collapse;margin:1em 0;font-size:0.9em}}td,th{{border:1px solid #bbb;padding:3px 8px;text-align:right}}\
th{{background:#eee}}.fig{{display:inline-block;margin:4px}}img{{max-width:100%}}pre{{background:#f6f6f6;padding:1em;overflow:auto;font-size:0.8em}}.answer{{display:flex;gap:2em;flex-wrap:wrap}}.answer th{{text-align:left}}\
</style></head><body>\n<h1>{0}</h1>\n{1}</body></html>\n",
            escape(&self.title),
            self.body
        )
    }
}
