"""``lander link``: connect and print the vehicle's state."""

from autonomy.cli import main


def test_link_to_the_embedded_simulator_prints_state(capsys, tmp_path):
    tlog = tmp_path / "link.tlog"
    code = main(["link", "sim://px4", "--duration", "7", "--tlog", str(tlog)])
    out = capsys.readouterr().out.splitlines()
    assert code == 0
    assert len([line for line in out if line.startswith("t=")]) == 7
    assert "px4" in out[0] and "AUTO.LOITER" in out[0]
    assert "prearm=ok" in out[6], "the simulator settles within 5 s"
    assert out[-1].startswith("sim://px4: ") and "corrupt bytes" in out[-1]
    assert tlog.stat().st_size > 0


def test_bad_url_is_one_line_and_exit_2(capsys):
    code = main(["link", "carrier-pigeon:7"])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2
    assert len(err) == 1 and "unknown link" in err[0]


def test_nothing_listening_exits_1(capsys):
    # udpin on an ephemeral port: nobody sends, so no autopilot is heard.
    code = main(["link", "udpin:127.0.0.1:0", "--duration", "0.3"])
    assert code == 1
    assert "no autopilot heard" in capsys.readouterr().out
