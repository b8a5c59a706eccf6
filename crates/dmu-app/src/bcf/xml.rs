//! A small element tree read with quick-xml, and the escaping writer: BCF's
//! files are kilobytes, so a tree is simpler to query than events, and element
//! names are matched without their namespace prefix.

use quick_xml::Reader;
use std::borrow::Cow;

use quick_xml::escape::{escape, resolve_predefined_entity};
use quick_xml::events::Event;

/// Elements nested deeper than this are refused (BCF nests about six deep).
const MAX_DEPTH: usize = 64;

/// One element: its local name, attributes, child elements and text.
#[derive(Debug, Default)]
pub(crate) struct Element {
    /// Local name (without a namespace prefix).
    pub name: String,
    /// Attributes by local name, unescaped, in document order.
    pub attributes: Vec<(String, String)>,
    /// Child elements in document order.
    pub children: Vec<Element>,
    /// The text directly inside, unescaped (not trimmed).
    pub text: String,
}

impl Element {
    /// The attribute `name`, if present.
    pub fn attribute(&self, name: &str) -> Option<&str> {
        self.attributes
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_str())
    }

    /// The first child element `name`.
    pub fn child(&self, name: &str) -> Option<&Element> {
        self.children.iter().find(|c| c.name == name)
    }

    /// Every child element `name`.
    pub fn children_named<'a>(&'a self, name: &'a str) -> impl Iterator<Item = &'a Element> {
        self.children.iter().filter(move |c| c.name == name)
    }

    /// The trimmed text of the child element `name`, if present.
    pub fn child_text(&self, name: &str) -> Option<&str> {
        self.child(name).map(|c| c.text.trim())
    }

    /// Every element below this one (not itself) named `name`, depth first.
    pub fn descendants_named<'a>(&'a self, name: &str, out: &mut Vec<&'a Element>) {
        for c in &self.children {
            if c.name == name {
                out.push(c);
            }
            c.descendants_named(name, out);
        }
    }
}

/// Parses a whole document into its root element. The error says what is wrong
/// and at which byte.
pub(crate) fn parse(bytes: &[u8]) -> Result<Element, String> {
    let mut reader = Reader::from_reader(bytes);
    let mut stack: Vec<Element> = Vec::new();
    let mut root: Option<Element> = None;
    let at = |reader: &Reader<&[u8]>| reader.buffer_position();
    loop {
        let event = reader
            .read_event()
            .map_err(|e| format!("bad XML at byte {}: {e}", reader.error_position()))?;
        let element = |e: &quick_xml::events::BytesStart<'_>| -> Result<Element, String> {
            let name = String::from_utf8_lossy(e.local_name().as_ref()).into_owned();
            let mut attributes = Vec::new();
            for a in e.attributes() {
                let a = a.map_err(|err| format!("bad attribute in <{name}>: {err}"))?;
                let value = a
                    .normalized_value(quick_xml::XmlVersion::Implicit1_0)
                    .map_err(|err| format!("bad attribute value in <{name}>: {err}"))?;
                attributes.push((
                    String::from_utf8_lossy(a.key.local_name().as_ref()).into_owned(),
                    value.into_owned(),
                ));
            }
            Ok(Element {
                name,
                attributes,
                ..Element::default()
            })
        };
        match event {
            Event::Start(e) => {
                if stack.len() >= MAX_DEPTH {
                    return Err(format!(
                        "elements nested more than {MAX_DEPTH} deep at byte {}",
                        at(&reader)
                    ));
                }
                let el = element(&e)?;
                if stack.is_empty() && root.is_some() {
                    return Err(format!("a second root element <{}>", el.name));
                }
                stack.push(el);
            }
            Event::Empty(e) => {
                let el = element(&e)?;
                match stack.last_mut() {
                    Some(parent) => parent.children.push(el),
                    None if root.is_some() => {
                        return Err(format!("a second root element <{}>", el.name));
                    }
                    None => root = Some(el),
                }
            }
            Event::End(_) => {
                let el = stack.pop().expect("quick-xml checks end names");
                match stack.last_mut() {
                    Some(parent) => parent.children.push(el),
                    None => root = Some(el),
                }
            }
            Event::Text(t) => {
                let text = t
                    .xml10_content()
                    .map_err(|e| format!("bad text at byte {}: {e}", at(&reader)))?;
                if let Some(top) = stack.last_mut() {
                    top.text.push_str(&text);
                }
            }
            Event::CData(t) => {
                let text = t
                    .decode()
                    .map_err(|e| format!("bad CDATA at byte {}: {e}", at(&reader)))?;
                if let Some(top) = stack.last_mut() {
                    top.text.push_str(&text);
                }
            }
            Event::GeneralRef(r) => {
                let resolved = if r.is_char_ref() {
                    r.resolve_char_ref().ok().flatten().map(String::from)
                } else {
                    r.decode()
                        .ok()
                        .and_then(|name| resolve_predefined_entity(&name).map(String::from))
                };
                let Some(resolved) = resolved else {
                    return Err(format!(
                        "unknown entity &{}; at byte {}",
                        String::from_utf8_lossy(&r),
                        at(&reader)
                    ));
                };
                if let Some(top) = stack.last_mut() {
                    top.text.push_str(&resolved);
                }
            }
            Event::Eof => break,
            Event::Comment(_) | Event::Decl(_) | Event::PI(_) | Event::DocType(_) => {}
        }
    }
    if let Some(open) = stack.last() {
        return Err(format!("the file ends inside <{}>", open.name));
    }
    root.ok_or_else(|| "no root element".to_owned())
}

/// `text` escaped for XML 1.0: markup characters as entities; a carriage
/// return (and in an attribute a tab or line feed) as a character reference,
/// since a reader normalises the bare ones; the characters XML 1.0 cannot hold
/// (most control characters, U+FFFE, U+FFFF) as U+FFFD.
pub(crate) fn xml_text(text: &str, attribute: bool) -> Cow<'_, str> {
    let plain =
        |c: char| matches!(c, '\u{20}'..='\u{D7FF}' | '\u{E000}'..='\u{FFFD}' | '\u{10000}'..);
    let escaped = escape(text);
    if escaped
        .chars()
        .all(|c| plain(c) || (!attribute && matches!(c, '\t' | '\n')))
    {
        return escaped;
    }
    let mut out = String::with_capacity(escaped.len() + 8);
    for c in escaped.chars() {
        match c {
            '\t' | '\n' if !attribute => out.push(c),
            '\t' => out.push_str("&#x9;"),
            '\n' => out.push_str("&#xA;"),
            '\r' => out.push_str("&#xD;"),
            c if plain(c) => out.push(c),
            _ => out.push('\u{FFFD}'),
        }
    }
    Cow::Owned(out)
}

/// An indented XML document written element by element, text and attributes
/// escaped.
#[derive(Debug)]
pub(crate) struct XmlWriter {
    out: String,
    open: Vec<&'static str>,
}

impl XmlWriter {
    /// A document with its UTF-8 declaration.
    pub fn new() -> Self {
        Self {
            out: "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n".to_owned(),
            open: Vec::new(),
        }
    }

    fn start_tag(&mut self, name: &str, attributes: &[(&str, &str)]) {
        self.out.push_str(&"  ".repeat(self.open.len()));
        self.out.push('<');
        self.out.push_str(name);
        for (key, value) in attributes {
            self.out
                .push_str(&format!(" {key}=\"{}\"", xml_text(value, true)));
        }
    }

    /// Opens `<name attributes…>`; [`Self::close`] ends it.
    pub fn open(&mut self, name: &'static str, attributes: &[(&str, &str)]) {
        self.start_tag(name, attributes);
        self.out.push_str(">\n");
        self.open.push(name);
    }

    /// Closes the element opened last.
    pub fn close(&mut self) {
        let name = self.open.pop().expect("an element is open");
        self.out.push_str(&"  ".repeat(self.open.len()));
        self.out.push_str(&format!("</{name}>\n"));
    }

    /// `<name attributes…/>`.
    pub fn empty(&mut self, name: &str, attributes: &[(&str, &str)]) {
        self.start_tag(name, attributes);
        self.out.push_str("/>\n");
    }

    /// `<name>text</name>`.
    pub fn leaf(&mut self, name: &str, text: &str) {
        self.start_tag(name, &[]);
        self.out
            .push_str(&format!(">{}</{name}>\n", xml_text(text, false)));
    }

    /// The document, every element closed.
    pub fn finish(self) -> String {
        assert!(self.open.is_empty(), "elements left open: {:?}", self.open);
        self.out
    }
}
