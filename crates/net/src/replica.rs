//! The client's state machine, free of any transport: local operations are applied at once and
//! sent; the room's order is applied as it arrives; local operations the room has not ordered
//! yet are rebased on it (taken back, the room's operation applied, put back), so that the
//! editor always holds the room's state after the last ordered operation plus the pending local
//! ones, and converges to the room's bytes when nothing is pending.
//!
//! Feed it with [`Replica::step`] once a frame (after [`Editor::frame`]): it takes the
//! operations the editor recorded, applies what arrived and says what to send.

use std::collections::VecDeque;

/// How many of our own ordered operations a replica keeps for redo (the room keeps no more
/// than its tail for undo), and how many dabs in them at most (about 100 bytes each).
const MINE_KEPT: usize = 4096;
const MINE_DABS: usize = 1 << 18;

/// How many undone strokes a replica keeps for redo.
const REDO_KEPT: usize = 64;

use strata_editor::{EditOp, Editor, OpUndo};

use crate::protocol::{ClientId, ClientMsg, Entry, Hello, Ordered, PROTOCOL, Peer, Resume, ResumeKey, Seq, ServerMsg};

/// A local operation the room has not ordered yet.
#[derive(Debug)]
struct Pending {
    number: u64,
    op: EditOp,
    /// What takes it back here; `None` when it could not be applied here (the room decides).
    undo: Option<OpUndo>,
}

/// What happened in a [`Replica::step`], for the user.
#[derive(Clone, Debug, PartialEq)]
pub enum Event {
    /// The room welcomed us.
    Joined {
        /// Our identity.
        client: ClientId,
    },
    /// The room replaced our scene with its snapshot.
    Snapshot,
    /// The room refused one of our operations (it was taken back).
    Refused(String),
    /// The room refused our undo (why).
    UndoRefused(String),
    /// The room undid one of our operations.
    Undone,
    /// An entry of the room's order was applied here (anyone's, ours included).
    Applied {
        /// Its place in the order.
        seq: Seq,
        /// Who made it.
        author: ClientId,
        /// The author's number for it (0 for an undo).
        number: u64,
    },
    /// Our scene's digest differed from the room's: a snapshot was asked for.
    Diverged,
    /// Someone joined or moved their brush.
    Presence(Peer, crate::protocol::Presence),
    /// Someone left.
    Left(ClientId),
    /// The room closed the connection.
    Closed {
        /// Why.
        reason: String,
        /// Whether connecting again may work (the room was closing, the server stopping); if
        /// not, a session that was joining stops trying.
        retry: bool,
    },
    /// Something arrived that this state machine cannot follow (a gap in the order, an
    /// operation that does not apply): a snapshot was asked for.
    OutOfStep(String),
}

/// The client's side of a room (see the module docs).
#[derive(Debug, Default)]
pub struct Replica {
    client: Option<ClientId>,
    /// The secret that proves our identity when reconnecting.
    key: Option<ResumeKey>,
    /// The last ordered operation applied.
    seq: Seq,
    /// Whether the room welcomed this connection (operations wait until it has).
    welcomed: bool,
    /// Whether a snapshot is due (asked for): ordered operations wait for it.
    awaiting_snapshot: bool,
    next_number: u64,
    pending: VecDeque<Pending>,
    /// Numbers already sent on this connection.
    sent: u64,
    /// After a welcome: the room's last operation then and the highest of our numbers it had
    /// handled. Once we have caught up with that operation, our pending operations up to that
    /// number that did not come back were refused (the refusal went to a connection that
    /// dropped).
    catch_up: Option<(Seq, u64)>,
    /// Whether the room's scene is here (a snapshot arrived): until then a resume asks for one.
    based: bool,
    /// Whether the pending operations are taken back (while the room's operations of one step
    /// are applied: they are put back once, at the end of the step).
    rewound: bool,
    /// Our newest operations the room ordered (at most [`MINE_KEPT`] and [`MINE_DABS`]), for
    /// redo.
    mine: VecDeque<(Seq, EditOp)>,
    /// The dabs in `mine`.
    mine_dabs: usize,
    /// Our strokes the room undid, newest last: what redo makes again.
    redo: Vec<Vec<EditOp>>,
    /// How a world that arrives in a snapshot streams here (see [`Replica::set_world_settings`]).
    world_settings: Option<strata_terrain::WorldSettings>,
}

impl Replica {
    /// A replica that has not joined yet.
    pub fn new() -> Self {
        Replica { next_number: 1, ..Replica::default() }
    }

    /// Our identity in the room, once welcomed.
    pub fn client(&self) -> Option<ClientId> {
        self.client
    }

    /// The last ordered operation applied.
    pub fn seq(&self) -> Seq {
        self.seq
    }

    /// The number given to our newest operation (0: none yet).
    pub fn last_number(&self) -> u64 {
        self.next_number.saturating_sub(1)
    }

    /// Local operations the room has not ordered yet.
    pub fn pending(&self) -> usize {
        self.pending.len()
    }

    /// Whether the room's scene is here (a snapshot arrived since the replica was made).
    pub fn has_scene(&self) -> bool {
        self.based
    }

    /// How a world that arrives in a snapshot (the room holds one, the editor does not) streams
    /// here; without this, as [`strata_terrain::WorldSettings::default`] says (at one level either
    /// way: see [`strata_editor::room`]).
    pub fn set_world_settings(&mut self, settings: strata_terrain::WorldSettings) {
        self.world_settings = Some(settings);
    }

    /// Whether there is an undone stroke of ours to redo.
    pub fn can_redo(&self) -> bool {
        !self.redo.is_empty()
    }

    /// Redoes our stroke the room undid last: its operations are made again, as a new stroke,
    /// applied here at once and sent at the next step (to the room they are new operations,
    /// which it may refuse like any). A new stroke of ours forgets what could be redone.
    pub fn redo(&mut self, editor: &mut Editor) -> Result<(), String> {
        let Some(stroke) = self.redo.pop() else { return Err("nothing to redo".into()) };
        let Some(number) = editor.claim_stroke() else {
            self.redo.push(stroke);
            return Err("the editor does not record operations".into());
        };
        for mut op in stroke {
            op.stroke = number;
            let undo = editor.replay(&op).ok();
            self.pending.push_back(Pending { number: self.next_number, op, undo });
            self.next_number += 1;
        }
        Ok(())
    }

    /// Whether the room welcomed the current connection.
    pub fn joined(&self) -> bool {
        self.welcomed
    }

    /// The hello for a new connection (resuming where this replica is, once it was in the
    /// room). Operations wait until the room answers.
    pub fn hello(&mut self, room: &str, token: &str, name: &str, create: Option<Vec<u8>>) -> ClientMsg {
        self.welcomed = false;
        self.sent = 0;
        ClientMsg::Hello(Hello {
            protocol: PROTOCOL,
            room: room.to_owned(),
            token: token.to_owned(),
            name: name.to_owned(),
            // A replica without the room's scene, or waiting for a snapshot it asked for (the
            // answer may have been lost with the connection), asks for one.
            resume: self
                .key
                .map(|key| Resume { key, seq: (self.based && !self.awaiting_snapshot).then_some(self.seq) }),
            create,
        })
    }

    /// The connection dropped: what was sent may or may not have arrived.
    pub fn disconnected(&mut self) {
        self.welcomed = false;
        self.sent = 0;
    }

    /// Takes the editor's new operations (pending from now on), applies `incoming` in order
    /// and returns what to send and what happened.
    pub fn step(&mut self, editor: &mut Editor, incoming: impl IntoIterator<Item = ServerMsg>) -> Step {
        let mut step = Step::default();
        self.capture(editor, &mut step);
        for msg in incoming {
            if !matches!(msg, ServerMsg::Op(_)) {
                self.unwind(editor);
            }
            self.receive(editor, msg, &mut step);
            self.settle(editor, &mut step);
        }
        self.unwind(editor);
        if self.welcomed {
            for p in self.pending.iter().filter(|p| p.number > self.sent) {
                step.send.push(ClientMsg::Submit { number: p.number, op: Box::new(p.op.clone()) });
            }
            if let Some(last) = self.pending.back() {
                self.sent = self.sent.max(last.number);
            }
        }
        step
    }

    /// Makes the editor's recorded operations pending. One a room would refuse as out of
    /// bounds (see [`crate::validate`]) is taken back here at once, with an event, instead of
    /// being sent.
    fn capture(&mut self, editor: &mut Editor, step: &mut Step) {
        let ops = editor.take_ops();
        if !ops.is_empty() {
            // New work: what was undone before it cannot be redone on top of it.
            self.redo.clear();
        }
        let bad: Vec<Option<crate::Invalid>> =
            ops.iter().map(|r| crate::validate(&r.op, editor, &crate::Limits::default()).err()).collect();
        if bad.iter().all(Option::is_none) {
            for recorded in ops {
                let number = self.next_number;
                self.next_number += 1;
                self.pending.push_back(Pending { number, op: recorded.op, undo: Some(recorded.undo) });
            }
            return;
        }
        // Everything applied since the last step is taken back in the reverse order it was
        // applied, then the pending work; the good operations go back on without the bad.
        let mut good = Vec::new();
        for (recorded, why) in ops.into_iter().zip(bad).rev() {
            if let Err((e, _)) = editor.revert(recorded.undo) {
                step.events.push(Event::OutOfStep(e.to_string()));
            }
            match why {
                Some(e) => step.events.push(Event::Refused(format!("not sent to the room: {e}"))),
                None => good.push(recorded.op),
            }
        }
        self.rewind(editor, 0);
        for op in good.into_iter().rev() {
            let number = self.next_number;
            self.next_number += 1;
            self.pending.push_back(Pending { number, op, undo: None });
        }
        self.replay_from(editor, 0);
    }

    fn receive(&mut self, editor: &mut Editor, msg: ServerMsg, step: &mut Step) {
        match msg {
            ServerMsg::Welcome { client, key, acked, seq, peers } => {
                self.key = Some(key);
                if self.client != Some(client) {
                    // A new identity: nothing of ours was ordered under it; renumber what is
                    // pending from 1. What we could redo referred to the old one's entries.
                    self.client = Some(client);
                    self.mine.clear();
                    self.mine_dabs = 0;
                    self.redo.clear();
                    for (k, p) in self.pending.iter_mut().enumerate() {
                        p.number = k as u64 + 1;
                    }
                    self.next_number = self.pending.len() as u64 + 1;
                }
                self.welcomed = true;
                // The room wants numbers after the highest it handled.
                self.next_number = self.next_number.max(acked + 1);
                // What the room ordered comes in the tail or is in the snapshot; resend the rest.
                self.sent = acked;
                self.catch_up = Some((seq, acked));
                step.events.push(Event::Joined { client });
                for peer in peers {
                    step.events.push(Event::Presence(peer, crate::protocol::Presence { position: None, radius: 0.0 }));
                }
            }
            ServerMsg::Snapshot { seq, acked, scene } => self.snapshot(editor, seq, acked, &scene, step),
            ServerMsg::Op(ordered) => {
                if self.awaiting_snapshot {
                    return;
                }
                if ordered.seq != self.seq + 1 {
                    let why = format!("operation {} arrived after {}", ordered.seq, self.seq);
                    self.out_of_step(why, step);
                    return;
                }
                let undone = Some(ordered.author) == self.client && matches!(ordered.entry, Entry::Undo { .. });
                let applied = Event::Applied { seq: ordered.seq, author: ordered.author, number: ordered.number };
                match self.apply_ordered(editor, ordered) {
                    Ok(()) => {
                        step.events.push(applied);
                        if undone {
                            step.events.push(Event::Undone);
                        }
                    }
                    Err(why) => self.out_of_step(why, step),
                }
            }
            ServerMsg::Refused { number, reason } => {
                if let Some(i) = self.pending.iter().position(|p| p.number == number) {
                    // (Taking back from it on takes it back too.)
                    self.rewind(editor, i);
                    self.pending.remove(i);
                    self.replay_from(editor, i);
                }
                step.events.push(Event::Refused(reason));
            }
            ServerMsg::Hash { seq, hash } => {
                // Only the room's state can be compared: with nothing pending, ours is it.
                if seq == self.seq
                    && self.pending.is_empty()
                    && !self.awaiting_snapshot
                    && crate::state_hash(&editor.scene) != Some(hash)
                {
                    self.awaiting_snapshot = true;
                    step.send.push(ClientMsg::Resync);
                    step.events.push(Event::Diverged);
                }
            }
            ServerMsg::UndoRefused { reason } => step.events.push(Event::UndoRefused(reason)),
            ServerMsg::Presence { peer, presence } => step.events.push(Event::Presence(peer, presence)),
            ServerMsg::Left { client } => step.events.push(Event::Left(client)),
            ServerMsg::Error { reason, retry } => {
                self.welcomed = false;
                step.events.push(Event::Closed { reason, retry });
            }
        }
    }

    /// Drops what the room refused while we were away, once caught up (see `catch_up`).
    fn settle(&mut self, editor: &mut Editor, step: &mut Step) {
        let Some((seq, acked)) = self.catch_up else { return };
        if self.seq < seq || self.awaiting_snapshot {
            return;
        }
        self.unwind(editor);
        self.catch_up = None;
        let Some(i) = self.pending.iter().position(|p| p.number <= acked) else { return };
        self.rewind(editor, i);
        let before = self.pending.len();
        let mut k = 0;
        self.pending.retain(|p| {
            k += 1;
            k <= i || p.number > acked
        });
        self.replay_from(editor, i);
        for _ in self.pending.len()..before {
            step.events.push(Event::Refused("the room refused an operation while we were away".into()));
        }
    }

    /// The room's next operation: ours (confirmed: it is already applied here unless it could
    /// not be) or someone else's (rebased under what is pending).
    fn apply_ordered(&mut self, editor: &mut Editor, ordered: Ordered) -> Result<(), String> {
        let ours =
            Some(ordered.author) == self.client && self.pending.front().is_some_and(|p| p.number == ordered.number);
        if ours && !self.rewound && self.pending.front().is_some_and(|p| p.undo.is_some()) {
            let p = self.pending.pop_front().expect("checked");
            self.seq = ordered.seq;
            self.keep_mine(ordered.seq, p.op);
            return Ok(());
        }
        // Pending work is taken back once for all the room's operations of this step.
        if !self.rewound {
            self.rewind(editor, 0);
            self.rewound = true;
        }
        let seq = ordered.seq;
        let by_us = Some(ordered.author) == self.client;
        let result = match ordered.entry {
            Entry::Edit(op) => {
                let r = editor.replay(&op).map(drop).map_err(|e| format!("operation {seq}: {e}"));
                if by_us {
                    self.keep_mine(seq, *op);
                }
                r
            }
            Entry::Undo { undo, of } => {
                if by_us {
                    self.undone(&of);
                }
                undo.into_iter().try_for_each(|u| editor.revert(u).map_err(|(e, _)| format!("undo {seq}: {e}")))
            }
        };
        if ours {
            self.pending.pop_front();
        }
        self.seq = seq;
        result
    }

    /// Keeps our operation ordered at `seq` for redo.
    fn keep_mine(&mut self, seq: Seq, op: EditOp) {
        self.mine_dabs += op.dabs.len();
        self.mine.push_back((seq, op));
        while self.mine.len() > MINE_KEPT || self.mine_dabs > MINE_DABS {
            let Some((_, old)) = self.mine.pop_front() else { break };
            self.mine_dabs -= old.dabs.len();
        }
    }

    /// The room undid our operations `of`: they become the newest stroke to redo.
    fn undone(&mut self, of: &[Seq]) {
        let mut stroke: Vec<(Seq, EditOp)> = Vec::new();
        self.mine.retain(|(seq, op)| {
            let hit = of.contains(seq);
            if hit {
                stroke.push((*seq, op.clone()));
            }
            !hit
        });
        self.mine_dabs = self.mine.iter().map(|(_, op)| op.dabs.len()).sum();
        // (A stroke only partly kept here cannot be made again whole.)
        if stroke.len() == of.len() && !stroke.is_empty() {
            stroke.sort_by_key(|(seq, _)| *seq);
            self.redo.push(stroke.into_iter().map(|(_, op)| op).collect());
            if self.redo.len() > REDO_KEPT {
                self.redo.remove(0);
            }
        }
    }

    /// Puts pending work back after the room's operations (see `rewound`).
    fn unwind(&mut self, editor: &mut Editor) {
        if self.rewound {
            self.rewound = false;
            self.replay_from(editor, 0);
        }
    }

    /// Takes back the pending operations from `i` on, newest first.
    fn rewind(&mut self, editor: &mut Editor, i: usize) {
        for p in self.pending.iter_mut().skip(i).rev() {
            if let Some(undo) = p.undo.take()
                && let Err((_, undo)) = editor.revert(undo)
            {
                // (Only a world's unreadable chunk refuses; keep the record so the state
                // stays explained.)
                p.undo = Some(undo);
            }
        }
    }

    /// Applies the pending operations from `i` on again, in order.
    fn replay_from(&mut self, editor: &mut Editor, i: usize) {
        for p in self.pending.iter_mut().skip(i) {
            if p.undo.is_none() {
                p.undo = editor.replay(&p.op).ok();
            }
        }
    }

    /// The room's snapshot replaces the scene (or the world's edited chunks); pending work
    /// the room has not ordered is put back on top of it. A snapshot of another kind than the
    /// editor holds (a world where it holds a scene, or the other way) gives the editor the
    /// room's content and drops what was pending (it was made on something else).
    fn snapshot(&mut self, editor: &mut Editor, seq: Seq, acked: u64, scene: &[u8], step: &mut Step) {
        let content = match strata_editor::room::decode(scene) {
            Ok(c) => c,
            Err(e) => {
                step.events.push(Event::OutOfStep(format!("the room's snapshot cannot be read: {e}")));
                return;
            }
        };
        // What the room ordered of ours is in the snapshot: only what it has not ordered stays
        // pending (sent or not, it comes back in the order after the snapshot).
        self.pending.retain(|p| p.number > acked);
        // A stroke in progress ends here (its operations so far are pending; the next frame
        // starts a new stroke, undone on its own).
        editor.end_stroke();
        let (mut tool, active) = (editor.tool, editor.active_layer);
        match editor.load_room(&content) {
            Ok(true) => {}
            Ok(false) => {
                let settings = editor
                    .world()
                    .map(|w| w.settings().clone())
                    .or_else(|| self.world_settings.clone())
                    .unwrap_or_default();
                match strata_editor::room::editor_for(content, settings) {
                    Ok(mut fresh) => {
                        fresh.record_ops(true);
                        *editor = fresh;
                        for _ in self.pending.drain(..) {
                            step.events.push(Event::Refused("made before the room's content arrived".into()));
                        }
                    }
                    Err(e) => {
                        step.events.push(Event::OutOfStep(format!("the room's snapshot cannot be opened: {e}")));
                        return;
                    }
                }
            }
            Err(e) => {
                step.events.push(Event::OutOfStep(format!("the room's snapshot cannot be loaded: {e}")));
                return;
            }
        }
        // (A material the room's palette lacks would make every stroke fail.)
        if tool.material as usize >= editor.scene.materials.len() {
            tool.material = 0;
        }
        editor.tool = tool;
        editor.active_layer = active.min(editor.scene.layers.len().saturating_sub(1));
        for p in self.pending.iter_mut() {
            p.undo = None;
        }
        self.replay_from(editor, 0);
        self.seq = seq;
        self.based = true;
        self.awaiting_snapshot = false;
        step.events.push(Event::Snapshot);
    }

    fn out_of_step(&mut self, why: String, step: &mut Step) {
        step.events.push(Event::OutOfStep(why));
        if !self.awaiting_snapshot {
            self.awaiting_snapshot = true;
            step.send.push(ClientMsg::Resync);
        }
    }
}

/// What a [`Replica::step`] produced.
#[derive(Debug, Default)]
pub struct Step {
    /// Messages to send, in order.
    pub send: Vec<ClientMsg>,
    /// What happened.
    pub events: Vec<Event>,
}
