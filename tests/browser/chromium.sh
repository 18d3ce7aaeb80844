#!/bin/sh
# Debian's Chromium for the tests, unable to raise its own priority. As root it sets its GPU and
# compositor threads to nice -8, ahead of the study server the tests measure on the same machine
# (a participant's browser runs on another); without CAP_SYS_NICE it stays at nice 0.
if [ "$(id -u)" = 0 ] && command -v setpriv >/dev/null 2>&1; then
  exec setpriv --inh-caps=-sys_nice --bounding-set=-sys_nice /usr/bin/chromium "$@"
fi
exec /usr/bin/chromium "$@"
