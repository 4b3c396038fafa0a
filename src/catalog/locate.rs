//! Maps field paths (`awg.divider[1].granularity`) to line numbers and back, so that every catalog
//! error can point at the line to fix. Built from `toml_edit`'s spans of the same text serde read.

use std::ops::Range;

use toml_edit::{ImDocument, Item, Table, Value};

/// Every key and array element of a TOML document with its path and byte span.
#[derive(Debug, Default)]
pub(crate) struct FieldIndex {
    entries: Vec<(String, Range<usize>)>,
    line_starts: Vec<usize>,
}

impl FieldIndex {
    /// Indexes `text`. Text that does not parse yields an index without fields (line lookups still work).
    pub(crate) fn new(text: &str) -> Self {
        let mut index = FieldIndex {
            entries: Vec::new(),
            line_starts: std::iter::once(0)
                .chain(text.match_indices('\n').map(|(i, _)| i + 1))
                .collect(),
        };
        if let Ok(doc) = ImDocument::parse(text) {
            index.walk_table(doc.as_table(), "");
        }
        index
    }

    /// The 1-based line of a byte offset.
    pub(crate) fn line_of(&self, offset: usize) -> usize {
        self.line_starts.partition_point(|&start| start <= offset)
    }

    /// The 1-based line where `path` is written, or where its nearest written parent is.
    pub(crate) fn line_of_path(&self, path: &str) -> Option<usize> {
        let mut candidate = path;
        loop {
            if let Some((_, span)) = self.entries.iter().find(|(p, _)| p == candidate) {
                return Some(self.line_of(span.start));
            }
            let cut = candidate.rfind(['.', '['])?;
            candidate = &candidate[..cut];
        }
    }

    /// The innermost field whose span contains `offset` (used to name the field of a serde error).
    pub(crate) fn path_at(&self, offset: usize) -> Option<&str> {
        self.entries
            .iter()
            .filter(|(_, span)| span.start <= offset && offset < span.end.max(span.start + 1))
            .min_by_key(|(_, span)| span.end - span.start)
            .map(|(path, _)| path.as_str())
    }

    fn push(&mut self, path: String, span: Option<Range<usize>>) {
        if let Some(span) = span {
            self.entries.push((path, span));
        }
    }

    fn walk_table(&mut self, table: &Table, prefix: &str) {
        for (name, _) in table.iter() {
            let Some((key, item)) = table.get_key_value(name) else {
                continue;
            };
            let path = join(prefix, name);
            match item {
                Item::Value(value) => {
                    let span = match (key.span(), value.span()) {
                        (Some(k), Some(v)) => Some(k.start..v.end),
                        (k, v) => k.or(v),
                    };
                    self.push(path.clone(), span);
                    self.walk_value(value, &path);
                }
                Item::Table(sub) => {
                    self.push(path.clone(), sub.span().or(key.span()));
                    self.walk_table(sub, &path);
                }
                Item::ArrayOfTables(array) => {
                    self.push(path.clone(), key.span());
                    for (i, sub) in array.iter().enumerate() {
                        let element = format!("{path}[{i}]");
                        self.push(element.clone(), sub.span());
                        self.walk_table(sub, &element);
                    }
                }
                Item::None => {}
            }
        }
    }

    fn walk_value(&mut self, value: &Value, path: &str) {
        match value {
            Value::Array(array) => {
                for (i, element) in array.iter().enumerate() {
                    let element_path = format!("{path}[{i}]");
                    self.push(element_path.clone(), element.span());
                    self.walk_value(element, &element_path);
                }
            }
            Value::InlineTable(table) => {
                for (name, _) in table.iter() {
                    if let Some((key, inner)) = table
                        .get_key_value(name)
                        .and_then(|(k, item)| Some((k, item.as_value()?)))
                    {
                        let inner_path = join(path, name);
                        let span = match (key.span(), inner.span()) {
                            (Some(k), Some(v)) => Some(k.start..v.end),
                            (k, v) => k.or(v),
                        };
                        self.push(inner_path.clone(), span);
                        self.walk_value(inner, &inner_path);
                    }
                }
            }
            _ => {}
        }
    }
}

fn join(prefix: &str, name: &str) -> String {
    if prefix.is_empty() {
        name.to_string()
    } else {
        format!("{prefix}.{name}")
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "a = 1\n[b]\nc = [1, 2]\n[[d]]\ne = { f = 3 }\n[[d]]\ne = { f = 4 }\n";

    #[test]
    fn paths_map_to_their_lines() {
        let index = FieldIndex::new(TEXT);
        assert_eq!(index.line_of_path("a"), Some(1));
        assert_eq!(index.line_of_path("b.c"), Some(3));
        assert_eq!(index.line_of_path("b.c[1]"), Some(3));
        assert_eq!(index.line_of_path("d[1].e.f"), Some(7));
        assert_eq!(index.line_of_path("d[1].missing"), Some(6));
    }

    #[test]
    fn offsets_map_to_the_innermost_field() {
        let index = FieldIndex::new(TEXT);
        let offset = TEXT.find("f = 4").unwrap() + 4;
        assert_eq!(index.path_at(offset), Some("d[1].e.f"));
        assert_eq!(index.line_of(offset), 7);
    }
}
