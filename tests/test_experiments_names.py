"""The experiments say "design" in Python and keep their database columns' names.

Renaming the ORM attributes (``Participant.design_name``,
``ExperimentSession.design_version_id``) must not rename the columns: study
databases written before the rename have to load as they are.
"""

from __future__ import annotations

import sqlite3

from tactilize.experiments.design_toml import load_design
from tactilize.experiments.flow import Flow
from tactilize.experiments.store import Store


def test_a_database_with_the_old_column_names_still_loads(tmp_path):
    db = tmp_path / "study.sqlite3"
    design = load_design("alpha-law")
    flow = Flow(design, Store(str(db)))
    token = flow.start("P01", True)["session"]
    flow.store.close()

    with sqlite3.connect(db) as con:
        participants = {row[1] for row in con.execute("PRAGMA table_info(participants)")}
        sessions = {row[1] for row in con.execute("PRAGMA table_info(sessions)")}
    assert "protocol_name" in participants and "design_name" not in participants
    assert "protocol_version_id" in sessions and "design_version_id" not in sessions

    again = Flow(design, Store(str(db), must_exist=True))
    sess = again.session_of(token)
    assert sess.design_version_id == again.design_version.id
    assert again.store.participant(sess).design_name == design.name == again.design.name
