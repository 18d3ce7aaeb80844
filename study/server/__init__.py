"""The study server's browser views (viser): the participant's page on the LAN and the
experimenter's console on 127.0.0.1, with the blinding guard, the MuJoCo scene and the paced
control loop. ``python -m study serve`` starts it (``study.cli.serve``)."""
