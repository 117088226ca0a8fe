"""What students run but do not read: the grader and the report. Nothing here is imported by hwlib."""
