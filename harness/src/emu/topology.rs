//! Who is cabled to whom, cable delays, and which links are up at a given true time.
//!
//! The chain is a tree rooted at the master: every slave's port 0 faces the master and its
//! ports 1..3 may lead to children (line, fork, cross). Link and power states are kept as
//! time-stamped change lists, so a frame's walk can ask "is this cable up at the instant the
//! frame reaches it" even for a break in the middle of the frame's round trip. REQ-ESC-080.

/// Tree, cables and time-indexed link/power state.
#[derive(Debug, Clone)]
pub struct Topology {
    /// (parent, parent port) of each slave; `None` = cabled to the master.
    pub parent: Vec<Option<(usize, u8)>>,
    /// Child behind each port.
    pub children: Vec<[Option<usize>; 4]>,
    /// Delay of the cable into each slave's port 0, ns.
    pub cable_ns: Vec<u64>,
    /// Up/down changes of the cable into each slave's port 0, sorted by time.
    link_changes: Vec<Vec<(u64, bool)>>,
    /// Power changes of each slave, sorted by time.
    power_changes: Vec<Vec<(u64, bool)>>,
    /// No change was ever scheduled: every link is up (fast path).
    all_static: bool,
}

fn state_at(changes: &[(u64, bool)], t: u64) -> bool {
    let n = changes.partition_point(|(x, _)| *x <= t);
    match n {
        0 => true,
        _ => changes[n - 1].1,
    }
}

fn insert_change(v: &mut Vec<(u64, bool)>, t: u64, up: bool) {
    let pos = v.partition_point(|(x, _)| *x <= t);
    v.insert(pos, (t, up));
}

impl Topology {
    /// Builds the tree from (parent, port) pairs and cable delays.
    pub fn new(parent: Vec<Option<(usize, u8)>>, cable_ns: Vec<u64>) -> Self {
        let n = parent.len();
        let mut children = vec![[None; 4]; n];
        for (i, p) in parent.iter().enumerate() {
            if let Some((p, port)) = p {
                children[*p][usize::from(*port)] = Some(i);
            }
        }
        Topology {
            parent,
            children,
            cable_ns,
            link_changes: vec![Vec::new(); n],
            power_changes: vec![Vec::new(); n],
            all_static: true,
        }
    }

    /// Number of slaves.
    pub fn len(&self) -> usize {
        self.parent.len()
    }

    /// No slaves.
    pub fn is_empty(&self) -> bool {
        self.parent.is_empty()
    }

    /// The link id (= the downstream slave) of the cable at `port` of `slave`.
    pub fn link_id(&self, slave: usize, port: u8) -> Option<usize> {
        if port == 0 {
            (slave < self.len()).then_some(slave)
        } else {
            self.children.get(slave)?.get(usize::from(port)).copied()?
        }
    }

    /// Records a cable state change.
    pub fn set_link(&mut self, link: usize, t: u64, up: bool) {
        if let Some(v) = self.link_changes.get_mut(link) {
            insert_change(v, t, up);
            self.all_static = false;
        }
    }

    /// Records a power change.
    pub fn set_power(&mut self, slave: usize, t: u64, on: bool) {
        if let Some(v) = self.power_changes.get_mut(slave) {
            insert_change(v, t, on);
            self.all_static = false;
        }
    }

    /// Slave powered at `t`.
    pub fn powered(&self, slave: usize, t: u64) -> bool {
        self.power_changes
            .get(slave)
            .is_some_and(|v| state_at(v, t))
    }

    /// No link or power change was ever scheduled: every link is up at every time.
    pub fn is_static(&self) -> bool {
        self.all_static
    }

    /// The cable into `slave`'s port 0 carries signal at `t`: cable intact and both ends
    /// powered (the master end always is).
    pub fn link_up(&self, slave: usize, t: u64) -> bool {
        if self.all_static {
            return slave < self.parent.len();
        }
        let cable = self.link_changes.get(slave).is_some_and(|v| state_at(v, t));
        let parent_on = match self.parent.get(slave) {
            Some(Some((p, _))) => self.powered(*p, t),
            Some(None) => true,
            None => false,
        };
        cable && parent_on && self.powered(slave, t)
    }
}
