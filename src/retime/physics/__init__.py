"""Physics-based retiming (McCann, Pollard, Srinivasa 2006): body model, path dynamics, contacts,
feasible regions and the timing optimizer."""
