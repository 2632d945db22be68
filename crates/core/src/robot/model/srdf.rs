//! The one part of a MoveIt SRDF the planner uses: its
//! `<disable_collisions link1="…" link2="…" reason="…"/>` elements, the
//! self-collision pairs MoveIt's setup assistant found never (or always)
//! in contact. They are added to the pairs [`crate::robot::model::import`] samples
//! itself, so a robot that already has a MoveIt configuration keeps its
//! decisions.

use quick_xml::events::Event;

/// One `<disable_collisions>` element.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct SrdfPair {
    pub link1: String,
    pub link2: String,
    /// The setup assistant's reason (`Adjacent`, `Never`, `Default`, …).
    pub reason: String,
}

/// Every `<disable_collisions>` of an SRDF's text; an error names the
/// element (by its position) and what is wrong with it.
pub fn disabled_collisions(text: &str) -> Result<Vec<SrdfPair>, String> {
    let mut reader = quick_xml::Reader::from_str(text);
    let mut out = Vec::new();
    let mut saw_robot = false;
    loop {
        let position = reader.buffer_position();
        let event = reader
            .read_event()
            .map_err(|e| format!("not XML at byte {position}: {e}"))?;
        let element = match &event {
            Event::Start(e) | Event::Empty(e) => e,
            Event::Eof => break,
            _ => continue,
        };
        match element.name().as_ref() {
            b"robot" => saw_robot = true,
            b"disable_collisions" => {
                let attribute = |name: &str| -> Result<Option<String>, String> {
                    element
                        .try_get_attribute(name)
                        .map_err(|e| format!("<disable_collisions> at byte {position}: {e}"))
                        .map(|a| a.map(|a| String::from_utf8_lossy(&a.value).into_owned()))
                };
                let (Some(link1), Some(link2)) = (attribute("link1")?, attribute("link2")?) else {
                    return Err(format!(
                        "<disable_collisions> at byte {position} needs link1 and link2"
                    ));
                };
                let reason = attribute("reason")?.unwrap_or_default();
                out.push(SrdfPair {
                    link1,
                    link2,
                    reason,
                });
            }
            _ => {}
        }
    }
    if !saw_robot {
        return Err("no <robot> element: not an SRDF".to_owned());
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_pairs_and_names_bad_elements() {
        let text = r#"<?xml version="1.0"?>
<robot name="r">
  <group name="arm"><joint name="j1"/></group>
  <disable_collisions link1="a" link2="b" reason="Adjacent"/>
  <disable_collisions link1="b" link2="c"></disable_collisions>
</robot>"#;
        let pairs = disabled_collisions(text).unwrap();
        assert_eq!(pairs.len(), 2);
        assert_eq!(
            (pairs[0].link1.as_str(), pairs[0].reason.as_str()),
            ("a", "Adjacent")
        );
        assert_eq!(
            (pairs[1].link2.as_str(), pairs[1].reason.as_str()),
            ("c", "")
        );
        let missing = disabled_collisions(r#"<robot><disable_collisions link1="a"/></robot>"#);
        assert!(missing.unwrap_err().contains("needs link1 and link2"));
        assert!(disabled_collisions("<robot><a></b></robot>").is_err());
        assert!(
            disabled_collisions("<urdf/>")
                .unwrap_err()
                .contains("not an SRDF")
        );
    }
}
