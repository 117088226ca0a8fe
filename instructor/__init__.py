"""What only instructors have: the release tool, the hidden checks and the wrong solutions. Left out of the student edition as one folder."""
