"""The guard every server of ours asks (``urdf2mjcf/loopback_guard.py``), fuzzed: for any
request line and headers a client can send, it answers or refuses without an error of
its own, and it answers only a loopback ``Host`` with the port, an allowed origin (or
none), and the run's token."""

from __future__ import annotations

from hypothesis import given, settings
from hypothesis import strategies as st

from urdf2mjcf.loopback_guard import Guard

PORT = 8123
TOKEN = "tok-EN_123456789abcdefgh"
GUARD = Guard(PORT, frozenset({"https://app.foxglove.dev"}), TOKEN)

text = st.text(st.characters(codec="latin-1"), max_size=80)
hosts = st.one_of(
    text,
    st.sampled_from(
        [f"localhost:{PORT}", f"127.0.0.1:{PORT}", f"[::1]:{PORT}", f"LOCALHOST:{PORT}",
         "localhost", f"localhost.:{PORT}", f"evil.test:{PORT}", f"127.0.0.2:{PORT}",
         f"localhost:{PORT}0", f"0x7f000001:{PORT}", f"2130706433:{PORT}"]
    ),
)  # fmt: skip
origins = st.one_of(
    text,
    st.sampled_from(
        [f"http://localhost:{PORT}", "https://app.foxglove.dev", "null", "http://evil.test",
         f"http://localhost:{PORT}.evil.test", "https://app.foxglove.dev.evil.test"]
    ),
)  # fmt: skip
targets = st.one_of(
    text,
    st.builds(lambda q: "/?" + q, text),
    st.sampled_from(
        [f"/?token={TOKEN}", f"/model?a=1&token={TOKEN}", "/?token=", f"/?token={TOKEN}x",
         "/?" + "&".join(["a=1"] * 100) + f"&token={TOKEN}"]
    ),
)  # fmt: skip
cookies = st.one_of(
    text, st.sampled_from([f"urdf2mjcf-{PORT}={TOKEN}", f"urdf2mjcf-1={TOKEN}", '"\\;=,'])
)


@settings(max_examples=3000, deadline=None)
@given(
    targets,
    st.lists(hosts, max_size=2),
    st.lists(origins, max_size=2),
    st.lists(st.one_of(text, st.sampled_from(["same-origin", "none", "cross-site"])), max_size=2),
    st.lists(cookies, max_size=2),
)
def test_the_guard_answers_only_our_own_requests(target, host, origin, site, cookie):
    refused = GUARD.check(target, host, origin, site, cookie)
    if refused is not None:
        assert refused.status == 403 and refused.reason
        return
    assert len(host) == 1 and host[0].strip().lower() in {
        f"localhost:{PORT}",
        f"127.0.0.1:{PORT}",
        f"[::1]:{PORT}",
    }
    assert len(origin) <= 1
    if origin:
        assert origin[0].strip().lower().rstrip("/") in {
            f"http://localhost:{PORT}",
            f"http://127.0.0.1:{PORT}",
            f"http://[::1]:{PORT}",
            "https://app.foxglove.dev",
        } or origin[0].lower().startswith("https://app.foxglove.dev:443")
    assert GUARD.token_in(target) or any(f"urdf2mjcf-{PORT}={TOKEN}" in c for c in cookie)


def test_the_users_own_page_is_answered():
    own = [f"localhost:{PORT}"]
    assert GUARD.check(f"/?token={TOKEN}", own, [], ["none"]) is None
    cookie = [f"urdf2mjcf-{PORT}={TOKEN}"]
    assert GUARD.check("/model", own, [f"http://localhost:{PORT}"], ["same-origin"], cookie) is None
    # the same request by another name, from another site, or without the token: refused
    assert GUARD.check("/model", [f"evil.test:{PORT}"], [], [], cookie) is not None
    assert GUARD.check("/model", own, ["http://evil.test"], [], cookie) is not None
    assert GUARD.check("/model", own, [], ["cross-site"], cookie) is not None
    assert GUARD.check("/model", own, [], ["same-origin"], []) is not None
