mod plant;
