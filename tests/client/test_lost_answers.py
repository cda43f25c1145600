"""Retries after an answer lost on the way back (the server acted, the client never heard) do
not act twice: a binding is stored once, a create or delete of a knowledge base that went
through is this call's success, not a 409 or a 404. The directory's real server on each
backend, a knowledge base of each test's own; the transport in between forwards each request and
drops the first answer to the chosen call."""

from __future__ import annotations

import uuid

import httpx
import pytest
from service_support import LiveServer

from client import Conflict, CpkbClient
from contract.bindings import BindingIn


class LosesFirstAnswer(httpx.BaseTransport):
    """Sends every request on; the first answer to `method path` is read, then lost."""

    def __init__(self, method: str, path: str) -> None:
        self.inner = httpx.HTTPTransport()
        self.method, self.path = method, path
        self.lost = 0

    def handle_request(self, request: httpx.Request) -> httpx.Response:
        response = self.inner.handle_request(request)
        if (request.method, request.url.path) == (self.method, self.path) and not self.lost:
            response.read()
            response.close()
            self.lost += 1
            raise httpx.ReadError("connection reset before the answer arrived", request=request)
        return response

    def close(self) -> None:
        self.inner.close()


@pytest.fixture
def server(shared_server: LiveServer) -> str:
    return shared_server.url


Kb = tuple[CpkbClient, str]


def client(url: str, transport: LosesFirstAnswer) -> CpkbClient:
    return CpkbClient(url, transport=transport, backoff=0.01)


def test_a_binding_whose_answer_was_lost_is_stored_once(kb_client: Kb, server: str) -> None:
    _, name = kb_client
    lossy = LosesFirstAnswer("POST", f"/v1/kbs/{name}/bindings")
    found = BindingIn(task="desk", skeleton="s" * 64, run="r", bindings={"#dir": "top"})
    with client(server, lossy) as kb:
        stored = kb.add_binding(name, found)
        listed = kb.bindings(name).bindings
    assert lossy.lost == 1
    assert [b.binding_id for b in listed] == [stored.binding_id]


def test_a_binding_key_names_one_binding(kb_client: Kb) -> None:
    kb, name = kb_client
    first = BindingIn(task="desk", skeleton="s" * 64, bindings={"#dir": "top"}, key="k1")
    assert kb.add_binding(name, first) == kb.add_binding(name, first)
    with pytest.raises(Conflict, match="k1"):
        kb.add_binding(name, first.model_copy(update={"bindings": {"#dir": "front"}}))
    assert len(kb.bindings(name).bindings) == 1


def test_a_create_and_a_delete_whose_answers_were_lost_succeed(server: str) -> None:
    lab = f"lab-{uuid.uuid4().hex[:10]}"
    lossy_create = LosesFirstAnswer("POST", "/v1/kbs")
    with client(server, lossy_create) as kb:
        created = kb.create_kb(lab)
    assert lossy_create.lost == 1 and created.name == lab

    lossy_delete = LosesFirstAnswer("DELETE", f"/v1/kbs/{lab}")
    with client(server, lossy_delete) as kb:
        kb.delete_kb(lab)
        names = [k.name for k in kb.list_kbs()]
    assert lossy_delete.lost == 1 and lab not in names

    with CpkbClient(server) as kb:  # sent once, a taken name is still the caller's error
        kb.create_kb(lab)
        with pytest.raises(Conflict):
            kb.create_kb(lab)
