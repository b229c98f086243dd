"""Test-suite configuration shared by every test folder."""

# The scripts that regenerate the committed fixtures import the tools that wrote them
# (pyrealsense2 needs the system's libusb): they are run by hand, never collected.
collect_ignore_glob = ["*/data/make_*.py"]
