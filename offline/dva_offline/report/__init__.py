"""dva report: what one recorded run says, as numbers, markdown, plots and a rerun file."""
